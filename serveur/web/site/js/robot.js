// The robot's own screen (the report's Robot UI, Appendix B): one big screen per status with
// big touch targets. URL: /robot/<name> or /robot.html?robot=<name>.
//
// Guests touch it: every status says what the robot does in their words, never the robot's raw
// navigation error (that is shown only to staff logged in here). At the pass (Loading) it tells
// staff which dishes go on which tray for which table, and Go sends the trip; at a table it
// names the tray to take, "Food collected" goes on, and a small Skip is set apart for staff.

import { Connection } from "./ws.js";
import { Live } from "./live.js";
import { act, confirmDialog, el, showError, watchConnection } from "./ui.js";
import { statusColour } from "./status.js";
import { applySiteLanguages, dishLabel, onLangChange, statusName, t } from "./i18n.js";

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

/** Staff are logged in on this screen (not the robot's own token): they may see more. */
function staffHere() {
  return Boolean(conn.session && conn.session.scopes.includes("control"));
}

/** What the screen shows, as plain data: drawn again only when it changes. */
function model(robot) {
  const task = robot.current_task === null ? null : live.tasks.get(robot.current_task) || null;
  const stop = task ? task.stops[task.current_stop] || null : null;
  const staff = staffHere();
  return {
    status: robot.status,
    resume: robot.resume,
    dest: live.destination(name),
    staff,
    // Tray k holds the dishes of the stop with seq k-1 (stops in visiting order).
    tray: stop ? stop.seq + 1 : null,
    // The robot's raw navigation error is for staff: guests never read "move_base ABORTED".
    error: staff && robot.status === "Error" ? robot.last_error : null,
    trays:
      robot.status === "Loading" && task
        ? [...task.stops]
            .sort((a, b) => a.seq - b.seq)
            .map((s) => ({
              tray: s.seq + 1,
              table: s.table,
              dishes: s.orders.map((id) => (live.orders.has(id) ? dishLabel(live.orders.get(id)) : null)),
            }))
        : [],
    cart: robot.status === "Delivered" ? cart.map(dishLabel) : [],
  };
}

function dishItems(labels) {
  return labels.length
    ? labels.map((label) => el("li", {}, label ?? t("robot.cartLoading")))
    : [el("li", { class: "muted" }, t("robot.cartLoading"))];
}

/** The small controls only staff should press, set apart from the guest's big buttons. */
function staffControls(...buttons) {
  const shown = buttons.filter(Boolean);
  if (!shown.length) return null;
  return el(
    "div",
    { class: "staff-controls", role: "group", "aria-label": t("guest.robot.forStaff") },
    el("span", { class: "staff-label", "aria-hidden": "true" }, t("guest.robot.forStaff")),
    ...shown,
  );
}

async function skipTable(button, table) {
  const yes = await confirmDialog(t("guest.robot.skipQuestion", { table }), {
    yes: t("guest.robot.skipYes"),
    no: t("guest.robot.skipNo"),
    detail: t("guest.robot.skipDetail"),
  });
  if (yes) await send(button, "skip");
}

function smallButton(label, onclick) {
  return el("button", { class: "secondary small", onclick: (e) => onclick(e.currentTarget), text: label });
}

function view(m) {
  const dest = m.dest;
  switch (m.status) {
    case "Ready":
      return [
        el("p", { class: "hello" }, t("robot.hello", { name })),
        // Activating is staff's call (the screen's own token may not); staff logged in here may.
        ...(m.staff
          ? [
              bigButton(t("robot.activate"), (b) => act(b, () => request({ clientmsg: "control", action: "auto" }))),
              el("p", { class: "sub" }, t("robot.activateSub")),
            ]
          : [el("p", { class: "sub" }, t("robot.staffActivate"))]),
      ];
    case "Awaiting":
      return [el("p", { class: "hello" }, t("robot.hello", { name })), el("h1", {}, t("robot.awaiting"))];
    case "Loading":
      // Staff at the pass: which dishes go on which tray for which table, then Go.
      return [
        el("h1", {}, t("robot.loading")),
        el("p", { class: "sub" }, t("robot.loadingSub")),
        m.trays.length
          ? el(
              "ol",
              { class: "trays", "aria-label": t("guest.robot.trays") },
              m.trays.map((tr) =>
                el(
                  "li",
                  { class: "tray", "data-tray": tr.tray },
                  el("h2", { class: "tray-head" }, t("guest.robot.trayTo", { tray: tr.tray, table: tr.table })),
                  el("ul", { class: "tray-dishes", "aria-label": t("guest.trayDishes", { tray: tr.tray }) }, dishItems(tr.dishes)),
                ),
              ),
            )
          : null,
        bigButton(t("guest.robot.go"), (b) => send(b, "go")),
        el("p", { class: "sub" }, t("guest.robot.goHint")),
      ];
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
        el("h1", {}, m.status === "Stopped" ? t("robot.stopped") : t("robot.stuck")),
        m.status === "Error" ? el("p", { class: "help" }, t("guest.robot.needHelp")) : null,
        // What went wrong, in the robot's own words: only for staff logged in on this screen.
        m.error ? el("p", { class: "sub detail" }, t("robot.lastError", { message: m.error })) : null,
        el(
          "p",
          { class: "sub" },
          m.resume === "Transit" ? t("robot.onWayHome") : dest ? t("robot.onWayTo", { table: dest }) : "",
        ),
        // Stopped (anyone may have pressed Stop): Continue and Cancel are big. In Error the
        // guest is asked to wait for staff, so every way out is a staff control.
        m.status === "Stopped"
          ? el(
              "div",
              { class: "choices" },
              bigButton(t("robot.continue"), (b) => send(b, "continue")),
              bigButton(t("robot.cancel"), (b) => cancelTrip(b), "danger"),
            )
          : null,
        staffControls(
          m.status === "Error" ? smallButton(t("robot.continue"), (b) => send(b, "continue")) : null,
          m.status === "Error" ? smallButton(t("robot.cancel"), (b) => cancelTrip(b)) : null,
          dest && m.resume !== "Transit" ? smallButton(t("guest.robot.skip"), (b) => skipTable(b, dest)) : null,
        ),
      ];
    case "Delivered":
      return [
        el("p", { class: "sub" }, t("robot.arrived")),
        el("h1", { class: "destination" }, dest ? t("robot.table", { table: dest }) : t("robot.yourTable")),
        m.tray ? el("p", { class: "take-tray" }, t("guest.takeTray", { tray: m.tray })) : null,
        el("ul", { class: "cart-items", "aria-label": t("robot.yourDishes") }, dishItems(m.cart)),
        bigButton(t("robot.collected"), (b) => send(b, "next")),
        staffControls(smallButton(t("guest.robot.skip"), (b) => skipTable(b, dest))),
      ];
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
  const m = model(robot);
  const signature = JSON.stringify(m);
  document.body.dataset.status = robot.status;
  const badge = document.getElementById("robot-status");
  badge.textContent = statusName(robot.status);
  badge.style.background = statusColour(robot.status);
  if (signature === shown) return;
  shown = signature;
  screen.replaceChildren(...view(m).filter(Boolean));
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
// The site's languages (the owner's settings): the picker offers them, and a screen with no
// choice of its own starts in the site's.
live.addEventListener("change", (e) => {
  if (e.detail.topic === "settings") applySiteLanguages(live.settings);
});
conn.subscribe(["robots", "tasks", "orders", "settings"]);
conn.start();
