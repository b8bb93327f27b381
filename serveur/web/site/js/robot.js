// The robot's own screen (the report's Robot UI, Appendix B): one big screen per status with
// big touch targets. URL: /robot/<name> or /robot.html?robot=<name>.
//
// Guests touch it: every status says what the robot does in their words, never the robot's raw
// navigation error (that is shown only to staff logged in here). At the pass (Loading) it tells
// staff which dishes go on which tray for which table, and Go sends the trip; at a table it
// names the tray to take, "Food collected" goes on, and a small Skip is set apart for staff.
// A dish's tray is the one staff chose for it, else its stop's (guest/trays.js).
// Arriving at a table it rings and says "Table T3, your food is here!" once (sound.js); with a
// special delivery (a birthday) it plays "Happy Birthday to You" instead. Bussing, cruising,
// special deliveries and charging have screens of their own (guest/robot-modes.js); while it
// cruises, any touch or key on the screen stops it.
//
// Staff sign in on the screen itself ("Staff sign-in", the pages' login dialog): an idle robot
// (Ready, Awaiting, or driven by staff) then offers "Send to a table" — a big button per table —
// and, once it stands somewhere, "Go home", with the verbs the console uses (`ready`, `control`
// `manual`, `goto`, `auto`: a robot-screen token may send none of them). The screen's own token
// stays the one the device keeps; staff are signed out after sending the robot, after
// STAFF_IDLE_MS without a touch, on "Sign out", and by a reload or a reconnect.

import { Connection, loadToken, saveToken } from "./ws.js";
import { Live } from "./live.js";
import { act, byName, confirmDialog, el, showError, toast, watchConnection } from "./ui.js";
import { statusColour } from "./status.js";
import { applySiteLanguages, dishLabel, lang, onLangChange, statusName, t } from "./i18n.js";
import { Announcer, muteButton, soundPrompt } from "./sound.js";
import { technicalNote } from "./staff/trouble.js";
import { listWords, stopTrays, tripTrays } from "./guest/trays.js";
import { modeView } from "./guest/robot-modes.js";
import { cruising, TouchToStop } from "./guest/cruise.js";
import { bigButton, dishItems, smallButton, staffControls, takeTray, yourDishes } from "./guest/widgets.js";

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

// The arrival chime and words; "Tap here to turn the sound on" above the screen while the
// browser holds sound back; the mute is the staff's (in their bar, below).
const announcer = new Announcer("robot");
screen.before(soundPrompt(announcer));
announcer.onChange(() => render()); // an arrival held back sounds once the sound is on
const mute = muteButton(announcer);
const staffBar = document.getElementById("staff-bar");
let staffShown = "";
// Cruising, the screen is a face: touched, the robot stops (guest/cruise.js).
const touch = new TouchToStop(live, name, request);

// Staff signed in on this screen (see the top): the device's own token, kept to come back to.
const STAFF_IDLE_MS = 120_000;
let turn = null; // {device: the screen's token, leaving: signing out} while staff sign in here
let idleTimer = null;
// Where an idle robot may be sent from its screen: not while it carries food or is driven home.
const SEND_FROM = new Set(["Ready", "Awaiting", "Manual"]);

function robotName() {
  const parts = window.location.pathname.split("/").filter(Boolean);
  if (parts[0] === "robot" && parts[1]) return decodeURIComponent(parts[1]);
  return new URLSearchParams(window.location.search).get("robot");
}

function request(msg) {
  return conn.request({ ...msg, robot: name });
}

function send(button, verb) {
  // Names the trip and stop this screen shows: refused (`stale`) if the robot moved on.
  return act(button, () => request({ clientmsg: verb, ...live.target(name) }));
}

const DELIVERY_CANCEL = {
  question: "robot.cancelQuestion",
  yes: "robot.cancelYes",
  no: "robot.cancelNo",
  detail: "robot.cancelDetail",
};

/** Cancel the trip, once the person said yes to `words` (the question's catalog keys). */
async function cancelTrip(button, words = DELIVERY_CANCEL) {
  const yes = await confirmDialog(t(words.question), { yes: t(words.yes), no: t(words.no), detail: t(words.detail) });
  if (yes) await act(button, () => request({ clientmsg: "cancel", ...live.target(name) }));
}

/** Staff are logged in on this screen (not the robot's own token): they may see more. */
function staffHere() {
  return Boolean(conn.session && conn.session.scopes.includes("control") && !turn?.leaving);
}

/** "Staff sign-in": the pages' login dialog (ui.js), for a person, on this connection. */
function staffSignIn() {
  if (!conn.session || conn.session.role !== "robot-screen") return;
  turn = { device: loadToken(), leaving: false };
  conn.dispatchEvent(new CustomEvent("login", { detail: { error: null } })); // ui.js opens its form
  const dialog = document.querySelector(".login-dialog");
  if (!dialog) return;
  if (!dialog.dataset.staffSignIn) {
    // Once: the device's own login cannot be skipped, a staff sign-in can (Cancel, Escape).
    dialog.dataset.staffSignIn = "1";
    dialog.addEventListener("cancel", cancelSignIn);
    dialog.addEventListener("close", () => dialog.querySelector(".login-cancel")?.remove());
  }
  if (dialog.querySelector(".login-cancel")) return;
  dialog.querySelector("form").append(
    el("button", { type: "button", class: "secondary login-cancel", onclick: cancelSignIn, text: t("guest.robot.staffCancel") }),
  );
}

/** The staff sign-in left before it succeeded: the robot's screen stays as it was. */
function cancelSignIn() {
  if (!turn || staffHere()) return;
  turn = null;
  document.querySelector(".login-dialog")?.close();
}

/** Back to the robot's own screen: the person's session ends, the device's token logs in. */
async function signOut() {
  if (!turn || turn.leaving) return;
  turn.leaving = true;
  clearTimeout(idleTimer);
  render();
  conn.unsubscribe(["waypoints"]); // a robot screen may not read them
  try {
    await conn.request({ clientmsg: "logout" });
  } catch {
    /* offline: the reconnect logs in with the device's token anyway */
  }
  if (turn?.device) conn.login({ token: turn.device });
}

function stillHere() {
  clearTimeout(idleTimer);
  if (turn && !turn.leaving && staffHere()) idleTimer = setTimeout(signOut, STAFF_IDLE_MS);
}

/** Run `steps` (requests for this robot) in order; the last reply, or null after an error. */
function steps(button, ...msgs) {
  return act(button, async () => {
    let reply = null;
    for (const msg of msgs) reply = await request(msg);
    return reply;
  });
}

/** Send the idle robot to `table`: out of deliveries, under staff control, then go-to. */
async function sendTo(button, table) {
  const status = live.robots.get(name)?.status;
  const msgs = [];
  if (status === "Awaiting") msgs.push({ clientmsg: "ready" });
  if (status === "Awaiting" || status === "Ready") msgs.push({ clientmsg: "control", action: "manual" });
  msgs.push({ clientmsg: "control", action: "goto", waypoint: table });
  if (await steps(button, ...msgs)) {
    toast(t("guest.robot.sentTo", { table }));
    signOut(); // the robot leaves the staff who sent it: the screen is the guests' again
  }
}

/** Home, and taking deliveries again (`auto` drives a robot away from home back to it). */
async function goHome(button) {
  if (await steps(button, { clientmsg: "ready" }, { clientmsg: "control", action: "auto" })) {
    toast(t("guest.robot.goingHome"));
    signOut();
  }
}

/** A dish of this robot's trips: the topic's newest copy, else the cart's answer; null if not loaded. */
function order(id) {
  return live.orders.get(id) || cart.find((o) => o.id === id) || null;
}

/** The robot's trip and its current stop (null, null when it has none). */
function currentStop(robot) {
  const task = robot.current_task === null ? null : live.tasks.get(robot.current_task) || null;
  return [task, task ? task.stops[task.current_stop] || null : null];
}

/** At the pass: each tray's tables and dishes (a dish named with its table when a tray has two). */
function loadingTrays(task) {
  return tripTrays(task, order).map((tr) => ({
    tray: tr.tray,
    tables: tr.tables,
    dishes: tr.dishes.map(({ order: o, table }) => {
      if (!o) return null;
      return tr.tables.length > 1 ? t("guest.robot.dishTo", { dish: dishLabel(o), table }) : dishLabel(o);
    }),
  }));
}

/** What the screen shows, as plain data: drawn again only when it changes. */
function model(robot) {
  const [task, stop] = currentStop(robot);
  const staff = staffHere();
  // Cruising: the same face from place to place, so it is not drawn again at each.
  if (cruising(live, robot)) return { face: true, staff };
  const kind = task ? task.kind || "delivery" : null;
  const purpose = stop ? stop.purpose || "deliver" : null;
  // At a table with dishes: which trays they are on, and any special message among them.
  const here = robot.status === "Delivered" && purpose === "deliver" && stop.status === "arrived";
  const serving = here ? stopTrays(stop, order) : [];
  const several = serving.length > 1;
  const special = serving.flatMap((tr) => tr.orders).filter((o) => o && o.special).map((o) => o.special);
  return {
    status: robot.status,
    resume: robot.resume,
    dest: live.destination(name),
    staff,
    kind,
    purpose,
    arrived: Boolean(stop && stop.status === "arrived"),
    toDock: robot.to_dock === true, // in Transit: to its charger, not home
    take: serving.map((tr) => tr.tray),
    // The robot's raw navigation error is for staff: guests never read "move_base ABORTED".
    error: staff && robot.status === "Error" ? robot.last_error : null,
    trays: robot.status === "Loading" && task ? loadingTrays(task) : [],
    // A dish named with its tray when the stop's dishes are on several.
    cart: serving.flatMap((tr) =>
      tr.orders.map((o) => {
        if (!o) return null;
        return several ? t("guest.dishOnTray", { tray: tr.tray, dish: dishLabel(o) }) : dishLabel(o);
      }),
    ),
    special,
    // "Play the song again" is offered while the screen's sound is not turned off.
    sound: special.length > 0 && announcer.state !== "off",
    // Charging: how full, in whole percent (drawn again only when that number changes).
    battery: robot.status === "Charging" && typeof robot.battery === "number" ? Math.round(robot.battery * 100) : null,
    // Staff here and the robot idle: where it may be sent.
    tables:
      staff && SEND_FROM.has(robot.status)
        ? [...live.waypoints.values()].filter((w) => w.kind === "table").map((w) => w.name).sort(byName)
        : null,
  };
}

/** "Send to a table" (a button per table) and "Go home", for staff at an idle robot. */
function sendPanel(m) {
  if (!m.tables) return null;
  return el(
    "section",
    { class: "send", "aria-labelledby": "send-title" },
    // First, where a phone shows it without scrolling. Ready: "Activate" above goes home too;
    // Awaiting: it is at home.
    m.status === "Manual" ? bigButton(t("guest.robot.goHome"), (b) => goHome(b), "secondary") : null,
    el("h2", { id: "send-title" }, t("guest.robot.sendTitle")),
    m.tables.length
      ? el(
          "div",
          { class: "table-grid" },
          m.tables.map((table) =>
            el("button", { type: "button", class: "table-button", onclick: (e) => sendTo(e.currentTarget, table), text: table }),
          ),
        )
      : el("p", { class: "sub" }, t("guest.robot.noTables")),
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

/** "Happy Birthday to You" again, for the guests who asked (a press lets the sound through). */
async function singAgain(button) {
  button.disabled = true;
  try {
    await announcer.singAgain();
  } finally {
    button.disabled = false;
  }
}

// What the screens of the other modes (guest/robot-modes.js) may ask of this robot.
const acts = {
  send,
  cancel: (button, words) => cancelTrip(button, words),
  skip: (button) => skipTable(button, live.destination(name)),
  singAgain,
  stopCruise: () => touch.touched(),
};

function view(m) {
  const mode = modeView(m, acts);
  if (mode) return mode;
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
        sendPanel(m),
      ];
    case "Awaiting":
      return [el("p", { class: "hello" }, t("robot.hello", { name })), el("h1", {}, t("robot.awaiting")), sendPanel(m)];
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
                  el("h2", { class: "tray-head" }, t("guest.robot.trayTo", { tray: tr.tray, table: listWords(tr.tables) })),
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
        el("h1", {}, m.toDock ? t("guest.robot.toCharge") : t("robot.returning")),
        bigButton(t("robot.stop"), (b) => send(b, "stop"), "danger"),
      ];
    case "Stopped":
    case "Error":
      return [
        el("h1", {}, m.status === "Stopped" ? t("robot.stopped") : t("robot.stuck")),
        m.status === "Error" ? el("p", { class: "help" }, t("guest.robot.needHelp")) : null,
        // What went wrong, for staff logged in on this screen: in their words, the robot's own
        // folded under "For the technician" (staff/trouble.js, as on the console's cards).
        m.error
          ? el("div", { class: "sub detail" }, dest ? t("trouble.stuckGoing", { place: dest }) : t("trouble.stuck"), technicalNote(m.error))
          : null,
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
        takeTray(m.take),
        yourDishes(m),
        bigButton(t("robot.collected"), (b) => send(b, "next")),
        staffControls(smallButton(t("guest.robot.skip"), (b) => skipTable(b, dest))),
      ];
    case "Manual":
      return [el("h1", {}, t("robot.manual")), el("p", { class: "sub" }, t("robot.keepClear")), sendPanel(m)];
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

/**
 * At a table with food: ring and say so, once per stop (sound.js keeps which on the device);
 * with a special dish, the birthday song instead; come for the plates, ring and ask for them.
 */
function announceArrival(robot) {
  // The site's settings choose the language a screen starts in: wait for them to speak it.
  if (robot.status !== "Delivered" || robot.current_task === null || !live.settings) return;
  const [task, stop] = currentStop(robot);
  // Reached: not the next stop of a trip whose update came before the robot's own.
  if (!stop || stop.status !== "arrived") return;
  const key = `${name}:${task.id}:${stop.seq}`;
  const purpose = stop.purpose || "deliver";
  if (purpose === "collect") announcer.announce(key, t("guest.arrival.plates"), lang());
  if (purpose !== "deliver") return; // the dish return, a cruise's place: nothing to ring
  const dishes = stop.orders.map(order);
  if (dishes.includes(null)) return; // which trays, or the song: once its dishes are known
  if (dishes.some((o) => o.special)) {
    announcer.sing(key);
    return;
  }
  const trays = stopTrays(stop, order).map((tr) => tr.tray);
  const tray = listWords(trays.length ? trays : [stop.seq + 1]);
  announcer.announce(key, t("guest.arrival.spokenAt", { table: stop.table, tray }), lang());
}

/** The footer's staff corner: "Staff sign-in" for a guest's screen; the mute and "Sign out" for staff. */
function renderStaffBar() {
  const role = conn.session ? conn.session.role : null;
  const staff = staffHere();
  const signature = JSON.stringify([role, staff, Boolean(turn), lang()]);
  if (signature === staffShown) return;
  staffShown = signature;
  if (staff) {
    staffBar.replaceChildren(
      el("span", { class: "staff-label" }, t("guest.robot.forStaff")),
      mute,
      turn ? el("button", { type: "button", class: "secondary small", onclick: () => signOut(), text: t("guest.robot.staffDone") }) : null,
    );
  } else if (role === "robot-screen") {
    staffBar.replaceChildren(
      el("button", { type: "button", class: "secondary small", onclick: () => staffSignIn(), text: t("guest.robot.staffSignIn") }),
    );
  } else {
    staffBar.replaceChildren();
  }
}

function render() {
  renderStaffBar();
  const robot = live.robots.get(name);
  if (!robot) {
    screen.replaceChildren(el("h1", {}, name ? t("robot.unknown", { name }) : t("robot.noName")));
    return;
  }
  refreshCart(robot);
  announceArrival(robot);
  const m = model(robot);
  if (!m.special?.length) announcer.hush(); // the birthday's robot moved on: so does its song
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
  if (["robots", "tasks", "orders", "waypoints"].includes(e.detail.topic)) render();
});
// What this screen may do depends on who it is.
conn.addEventListener("session", (e) => {
  const session = e.detail.session;
  if (turn?.device) saveToken(turn.device); // the device keeps its own token, never a person's
  if (session.scopes.includes("control")) {
    conn.subscribe(["waypoints"]); // the tables to send the robot to
    stillHere();
  } else {
    // The robot's own screen again (signed out, or a reconnect with the device's token).
    turn = null;
    clearTimeout(idleTimer);
    conn.topics.delete("waypoints"); // not asked for: a robot screen may not read them
    live.waypoints.clear();
  }
  render();
});
conn.addEventListener("login", () => {
  if (turn?.device) saveToken(turn.device); // a staff sign-in that failed leaves the device's token
});
// A touch or a key keeps staff signed in; STAFF_IDLE_MS without one signs them out.
window.addEventListener("pointerdown", stillHere, { capture: true });
window.addEventListener("keydown", stillHere, { capture: true });
// While it cruises, any touch or key anywhere on the screen stops the robot.
window.addEventListener("pointerdown", () => touch.touched(), { capture: true });
window.addEventListener("keydown", () => touch.touched(), { capture: true });
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
  if (e.detail.topic !== "settings") return;
  applySiteLanguages(live.settings);
  if (loaded) render(); // an arrival waits for the site's language to be said in
});
conn.subscribe(["robots", "tasks", "orders", "settings"]);
conn.start();
