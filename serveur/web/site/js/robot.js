// The robot's own screen (the report's Robot UI, Appendix B): one big screen per status with
// big touch targets. URL: /robot/<name> or /robot.html?robot=<name>.

import { Connection } from "./ws.js";
import { Live } from "./live.js";
import { act, confirmDialog, el, showError, watchConnection } from "./ui.js";
import { statusColour } from "./status.js";
import { onLangChange, statusName, t } from "./i18n.js";

const name = robotName();
const conn = new Connection();
const live = new Live(conn);
watchConnection(conn);
const screen = document.getElementById("screen");
document.getElementById("robot-name").textContent = name || "";

let cart = []; // the dishes for the current stop, from `order` {robot}
let cartFor = ""; // which stop the cart belongs to
let shown = "";
let loaded = false; // a robots snapshot came: "no robot named" can be said

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
  const yes = await confirmDialog(t("robot.cancelQuestion"), {
    yes: t("robot.cancelYes"),
    no: t("robot.cancelNo"),
    detail: t("robot.cancelDetail"),
  });
  if (yes) await act(button, () => request({ clientmsg: "cancel", ...live.target(name) }));
}

function view(robot) {
  const dest = live.destination(name);
  switch (robot.status) {
    case "Ready":
      return [
        el("p", { class: "hello" }, t("robot.hello", { name })),
        // Activating is staff's call (the screen's own token may not); staff logged in here may.
        ...(conn.session && conn.session.scopes.includes("control")
          ? [
              bigButton(t("robot.activate"), (b) => act(b, () => request({ clientmsg: "control", action: "auto" }))),
              el("p", { class: "sub" }, t("robot.activateSub")),
            ]
          : [el("p", { class: "sub" }, t("robot.staffActivate"))]),
      ];
    case "Awaiting":
      return [el("p", { class: "hello" }, t("robot.hello", { name })), el("h1", {}, t("robot.awaiting"))];
    case "Delivering":
      return [
        el("p", { class: "sub" }, t("robot.deliveringTo")),
        el("h1", { class: "destination" }, dest ? t("robot.table", { table: dest }) : t("robot.aTable")),
        bigButton(t("robot.stop"), (b) => send(b, "stop"), "danger"),
      ];
    case "Transit":
      return [
        el("h1", {}, t("robot.returning")),
        bigButton(t("robot.stop"), (b) => send(b, "stop"), "danger"),
      ];
    case "Stopped":
    case "Error":
      return [
        el("h1", {}, robot.status === "Stopped" ? t("robot.stopped") : t("robot.stuck")),
        // The robot's own error text, as the server sends it, after a word in this language.
        robot.last_error && robot.status === "Error"
          ? el("p", { class: "sub" }, t("robot.lastError", { message: robot.last_error }))
          : null,
        el(
          "p",
          { class: "sub" },
          robot.resume === "Transit" ? t("robot.onWayHome") : dest ? t("robot.onWayTo", { table: dest }) : "",
        ),
        el(
          "div",
          { class: "choices" },
          bigButton(t("robot.continue"), (b) => send(b, "continue")),
          bigButton(t("robot.cancel"), (b) => cancelTrip(b), "danger"),
        ),
      ];
    case "Delivered":
      return [
        el("p", { class: "sub" }, t("robot.arrived")),
        el("h1", { class: "destination" }, dest ? t("robot.table", { table: dest }) : t("robot.yourTable")),
        el(
          "ul",
          { class: "cart-items", "aria-label": t("robot.yourDishes") },
          cart.length ? cart.map((o) => el("li", {}, o.dish)) : el("li", { class: "muted" }, t("robot.cartLoading")),
        ),
        bigButton(t("robot.collected"), (b) => send(b, "next")),
      ];
    case "Loading":
      return [el("h1", {}, t("robot.loading")), el("p", { class: "sub" }, t("robot.loadingSub"))];
    case "Manual":
      return [el("h1", {}, t("robot.manual")), el("p", { class: "sub" }, t("robot.keepClear"))];
    default:
      return [el("h1", {}, t("robot.offline")), el("p", { class: "sub" }, t("robot.offlineSub"))];
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
    screen.replaceChildren(el("h1", {}, name ? t("robot.unknown", { name }) : t("robot.noName")));
    return;
  }
  refreshCart(robot);
  const signature = JSON.stringify([robot.status, robot.resume, robot.last_error, live.destination(name), cart.map((o) => o.id)]);
  document.body.dataset.status = robot.status;
  const badge = document.getElementById("robot-status");
  badge.textContent = statusName(robot.status);
  badge.style.background = statusColour(robot.status);
  if (signature === shown) return;
  shown = signature;
  screen.replaceChildren(...view(robot).filter(Boolean));
}

live.addEventListener("change", (e) => {
  if (e.detail.topic === "orders") cartFor = ""; // a dish changed: ask again for this stop
  if (e.detail.topic === "robots") loaded = true;
  if (["robots", "tasks", "orders"].includes(e.detail.topic)) render();
});
conn.addEventListener("session", () => render()); // what this screen may do depends on who it is
onLangChange(() => {
  document.title = t("robot.docTitle", { name: name || t("robot.docTitleNone") });
  shown = ""; // same robot, new words: draw again
  if (loaded || !name) render();
});
document.title = t("robot.docTitle", { name: name || t("robot.docTitleNone") });
if (!name) render();
conn.subscribe(["robots", "tasks", "orders"]);
conn.start();
