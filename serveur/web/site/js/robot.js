// The robot's own screen (the report's Robot UI, Appendix B): one big screen per status with
// big touch targets. URL: /robot/<name> or /robot.html?robot=<name>.

import { Connection } from "./ws.js";
import { Live } from "./live.js";
import { act, confirmDialog, el, showError, watchConnection } from "./ui.js";
import { statusColour } from "./status.js";

const name = robotName();
const conn = new Connection();
const live = new Live(conn);
watchConnection(conn);
const screen = document.getElementById("screen");
document.title = `serveur · ${name || "robot"}`;
document.getElementById("robot-name").textContent = name || "";

let cart = []; // the dishes for the current stop, from `order` {robot}
let cartFor = ""; // which stop the cart belongs to
let shown = "";

function robotName() {
  const parts = window.location.pathname.split("/").filter(Boolean);
  if (parts[0] === "robot" && parts[1]) return decodeURIComponent(parts[1]);
  return new URLSearchParams(window.location.search).get("robot");
}

function request(msg) {
  return conn.request({ ...msg, robot: name });
}

function bigButton(label, onclick, cls = "primary") {
  return el("button", { class: `big ${cls}`, onclick: (e) => onclick(e.currentTarget), text: label });
}

function send(button, verb) {
  // Names the trip and stop this screen shows: refused (`stale`) if the robot moved on.
  return act(button, () => request({ clientmsg: verb, ...live.target(name) }));
}

async function cancelTrip(button) {
  const yes = await confirmDialog("Cancel this delivery?", {
    yes: "Yes, cancel the delivery",
    no: "No, keep it",
    detail: "I will go back home; the dishes not yet served go back to the kitchen pass.",
  });
  if (yes) await act(button, () => request({ clientmsg: "cancel", ...live.target(name) }));
}

function view(robot) {
  const dest = live.destination(name);
  switch (robot.status) {
    case "Ready":
      return [
        el("p", { class: "hello" }, `Hello, I'm ${name}`),
        // Activating is staff's call (the screen's own token may not); staff logged in here may.
        ...(conn.session && conn.session.scopes.includes("control")
          ? [
              bigButton("Activate this robot", (b) => act(b, () => request({ clientmsg: "control", action: "auto" }))),
              el("p", { class: "sub" }, "to deliver orders"),
            ]
          : [el("p", { class: "sub" }, "Staff can activate me from the console.")]),
      ];
    case "Awaiting":
      return [el("p", { class: "hello" }, `Hello, I'm ${name}`), el("h1", {}, "Awaiting orders")];
    case "Delivering":
      return [
        el("p", { class: "sub" }, "Delivering to"),
        el("h1", { class: "destination" }, dest ? `Table ${dest}` : "a table"),
        bigButton("Stop", (b) => send(b, "stop"), "danger"),
      ];
    case "Transit":
      return [
        el("h1", {}, "Returning home"),
        bigButton("Stop", (b) => send(b, "stop"), "danger"),
      ];
    case "Stopped":
    case "Error":
      return [
        el("h1", {}, robot.status === "Stopped" ? "Stopped" : "I'm stuck"),
        robot.last_error && robot.status === "Error" ? el("p", { class: "sub" }, robot.last_error) : null,
        el("p", { class: "sub" }, robot.resume === "Transit" ? "on my way home" : dest ? `on my way to table ${dest}` : ""),
        el(
          "div",
          { class: "choices" },
          bigButton("Continue", (b) => send(b, "continue")),
          bigButton("Cancel", (b) => cancelTrip(b), "danger"),
        ),
      ];
    case "Delivered":
      return [
        el("p", { class: "sub" }, "Your order has arrived"),
        el("h1", { class: "destination" }, dest ? `Table ${dest}` : "Your table"),
        el(
          "ul",
          { class: "cart-items", "aria-label": "Your dishes" },
          cart.length ? cart.map((o) => el("li", {}, o.dish)) : el("li", { class: "muted" }, "…"),
        ),
        bigButton("Food collected", (b) => send(b, "next")),
      ];
    case "Manual":
      return [el("h1", {}, "Staff are driving me"), el("p", { class: "sub" }, "Please keep clear.")];
    default:
      return [el("h1", {}, "Offline"), el("p", { class: "sub" }, "Waiting for my connection to the server…")];
  }
}

function currentStopKey(robot) {
  if (robot.status !== "Delivered" || robot.current_task === null) return "";
  const task = live.tasks.get(robot.current_task);
  return task ? `${task.id}:${task.current_stop}` : `${robot.current_task}:?`;
}

async function refreshCart(robot) {
  const key = currentStopKey(robot);
  if (!key) {
    cart = [];
    cartFor = "";
    return;
  }
  if (key === cartFor) return;
  cartFor = key;
  try {
    const reply = await conn.request({ clientmsg: "order", robot: name }, { resend: true });
    if (cartFor === key) {
      cart = reply.orders;
      render();
    }
  } catch (err) {
    cartFor = "";
    showError(err);
  }
}

function render() {
  const robot = live.robots.get(name);
  if (!robot) {
    screen.replaceChildren(el("h1", {}, name ? `No robot named ${name}` : "No robot named in the address"));
    return;
  }
  refreshCart(robot);
  const signature = JSON.stringify([robot.status, robot.resume, robot.last_error, live.destination(name), cart.map((o) => o.id)]);
  document.body.dataset.status = robot.status;
  const badge = document.getElementById("robot-status");
  badge.textContent = robot.status;
  badge.style.background = statusColour(robot.status);
  if (signature === shown) return;
  shown = signature;
  screen.replaceChildren(...view(robot).filter(Boolean));
}

live.addEventListener("change", (e) => {
  if (e.detail.topic === "orders") cartFor = ""; // a dish changed: ask again for this stop
  if (["robots", "tasks", "orders"].includes(e.detail.topic)) render();
});
conn.addEventListener("session", () => render()); // what this screen may do depends on who it is
if (!name) render();
conn.subscribe(["robots", "tasks", "orders"]);
conn.start();
