// A table's screen: a robot standing at this table (which tray to take, its dishes, and a big
// "Food collected"; or, come for the used plates, "Please put your used plates on its trays"
// and Done), the guests' calls (a robot for the plates, a waiter, the bill: guest/calls.js),
// then the table's virtual cart — dishes on a robot and served (`order` {table}), plus the ones
// ready at the pass (the `orders` topic). The `tasks` topic brings only the trips with a stop at
// this table. URL: /table/<name> or ?table=<name>.
// Refreshed whenever an order or a trip of this table changes. A robot arriving here with food
// rings and says "Your food is here! Please take tray 1" once (sound.js); the footer's sound
// button mutes this screen. A dish's tray is the one staff chose, else its stop's (guest/trays.js).

import { Connection } from "./ws.js";
import { Live } from "./live.js";
import { act, el, KeyedList, showError, toast, watchConnection } from "./ui.js";
import { applySiteLanguages, dishLabel, lang, onLangChange, t } from "./i18n.js";
import { Announcer, muteButton, soundPrompt } from "./sound.js";
import { listWords, stopTrays } from "./guest/trays.js";
import { TableCalls } from "./guest/calls.js";

const table = tableName();
const conn = new Connection();
const live = new Live(conn);
watchConnection(conn);
function titles() {
  document.title = t("table.docTitle", { table: table || "" });
  document.getElementById("table-title").textContent = table ? t("table.title", { table }) : t("table.noName");
}
titles();
onLangChange(() => {
  titles();
  for (const rows of [herePanels, coming, served, atPass]) rows.invalidate(); // new words
  if (loaded) render();
});
const calls = table ? new TableCalls(conn, table, document.getElementById("calls")) : null;
if (!table) document.getElementById("calls").hidden = true;

let cart = [];
let asking = null;
let loaded = false; // the orders came: "nothing ..." can be said

// The arrival chime and words: "Tap here to turn the sound on" first on the page while the
// browser holds sound back, the mute beside the language.
const announcer = new Announcer("table");
document.querySelector(".table-main").prepend(soundPrompt(announcer));
document.querySelector(".table-footer").append(muteButton(announcer));
announcer.onChange(() => {
  if (loaded) render(); // an arrival held back sounds once the sound is on
});

// Each robot here, drawn again only when what it shows changed, so a redraw does not replace a
// button being pressed; and the three lists of dishes, one row per dish.
const herePanels = new KeyedList(document.getElementById("here"), {
  key: (here) => here.robot,
  signature: (here) => [here, trays(here).map((tr) => [tr.tray, tr.orders.map((o) => o && dishLabel(o))])],
  build: (here) => (here.purpose === "collect" ? platesPanel(here) : herePanel(here)),
});
const dishes = (id, empty) =>
  new KeyedList(document.getElementById(id), {
    key: (o) => o.id,
    signature: (o) => dishLabel(o),
    build: (o) => el("li", { "data-order": o.id }, el("span", { class: "dish" }, dishLabel(o))),
    empty: () => el("li", { class: "muted" }, t(empty)),
  });
const coming = dishes("coming", "table.comingEmpty");
const served = dishes("served", "table.servedEmpty");
const atPass = dishes("at-pass", "table.passEmpty");

function tableName() {
  const parts = window.location.pathname.split("/").filter(Boolean);
  if (parts[0] === "table" && parts[1]) return decodeURIComponent(parts[1]);
  return new URLSearchParams(window.location.search).get("table");
}

async function refresh() {
  if (!table) return;
  // Coalesce bursts of updates into one request at a time, plus one more if needed after it.
  if (asking) {
    asking.again = true;
    return;
  }
  asking = { again: false };
  try {
    cart = (await conn.request({ clientmsg: "order", table }, { resend: true })).orders;
    render();
  } catch (err) {
    showError(err);
  } finally {
    const again = asking.again;
    asking = null;
    if (again) refresh();
  }
}

/** The newest copy of an order: the topic's update, else the cart's answer. */
function order(id) {
  return live.orders.get(id) || cart.find((o) => o.id === id) || null;
}

// What a robot stopped here came for: dishes to take, or used plates to collect. A cruising
// robot pausing beside the table (a `visit`) asks nothing of this screen.
const HERE_FOR = new Set(["deliver", "collect"]);

/** The robots standing at this table now: trips whose current stop is here and reached. */
function arrivals() {
  const out = [];
  for (const task of live.tasks.values()) {
    const stop = task.status === "active" ? task.stops[task.current_stop] : null;
    const purpose = stop ? stop.purpose || "deliver" : null;
    const here = stop && stop.table === table && stop.status === "arrived" && task.robot;
    if (here && HERE_FOR.has(purpose)) {
      out.push({ robot: task.robot, task: task.id, stop: stop.seq, purpose, orders: stop.orders });
    }
  }
  return out;
}

/** A robot's dishes for this table by tray: the tray staff chose for a dish, else its stop's. */
function trays(here) {
  return stopTrays({ seq: here.stop, orders: here.orders }, order);
}

/** "Food collected" (or Done, the plates on): the robot goes on. */
async function collected(button, here) {
  const reply = await act(button, async () => {
    try {
      return await conn.request({ clientmsg: "next", robot: here.robot, task: here.task, stop: here.stop });
    } catch (err) {
      // The robot left (timed out, or staff skipped): say so in the guest's words.
      if (["stale", "forbidden", "not_allowed_in_status"].includes(err.code)) {
        toast(t("guest.table.movedOn"), { kind: "error" });
        return null;
      }
      throw err;
    }
  });
  if (reply && here.purpose !== "collect") toast(t("guest.table.enjoy"));
}

/** "Please take tray 1" (or trays 1 and 3), then the dishes on each tray. */
function herePanel(here) {
  const groups = trays(here);
  const numbers = groups.map((tr) => tr.tray);
  return el(
    "section",
    { class: "here", "data-robot": here.robot },
    el("h2", { class: "here-title" }, t("guest.table.here")),
    el(
      "p",
      { class: "take-tray" },
      numbers.length > 1
        ? t("guest.takeTrays", { trays: listWords(numbers) })
        : t("guest.takeTray", { tray: numbers[0] ?? here.stop + 1 }),
    ),
    groups.map((tr) =>
      el(
        "ul",
        { class: "here-dishes", "aria-label": t("guest.trayDishes", { tray: tr.tray }) },
        tr.orders.map((o) => el("li", {}, o ? dishLabel(o) : t("robot.cartLoading"))),
      ),
    ),
    el("button", { class: "big collected", onclick: (e) => collected(e.currentTarget, here), text: t("robot.collected") }),
    el("p", { class: "hint" }, t("guest.table.collectedHint")),
  );
}

/** A robot come for the used plates: put them on, then Done (it also goes on by itself). */
function platesPanel(here) {
  return el(
    "section",
    { class: "here plates", "data-robot": here.robot },
    el("h2", { class: "here-title" }, t("guest.table.platesHere")),
    el("p", { class: "put-plates" }, t("guest.table.putPlates")),
    el("button", { class: "big collected", onclick: (e) => collected(e.currentTarget, here), text: t("guest.robot.done") }),
    el("p", { class: "hint" }, t("guest.robot.putPlatesHint")),
  );
}

/** Each robot standing here with food (or for the plates): ring and say so, once per stop. */
function announce(here) {
  if (!live.settings) return; // the site's settings choose the language: wait to speak it
  for (const h of here) {
    const numbers = trays(h).map((tr) => tr.tray);
    const words =
      h.purpose === "collect"
        ? t("guest.arrival.plates")
        : t("guest.arrival.spoken", { tray: listWords(numbers.length ? numbers : [h.stop + 1]) });
    announcer.announce(`${table}:${h.robot}:${h.task}:${h.stop}`, words, lang());
  }
}

function render() {
  const here = arrivals();
  const onTray = new Set(here.flatMap((h) => h.orders));
  herePanels.update(here);
  announce(here);
  // On the way: on a robot, except the dishes of a robot already here (shown above).
  coming.update(cart.filter((o) => o.status === "assigned" && !onTray.has(o.id)));
  served.update(cart.filter((o) => o.status === "delivered"));
  atPass.update([...live.orders.values()].filter((o) => o.table === table && o.status === "pending"));
}

live.addEventListener("change", (e) => {
  const { topic, record } = e.detail;
  if (topic === "tasks") {
    if (loaded) render();
    return;
  }
  if (topic !== "orders" || (record && record.table !== table)) return;
  loaded = true;
  render();
  refresh();
});
// The site's languages (the owner's settings): the picker offers them, and a screen with no
// choice of its own starts in the site's.
live.addEventListener("change", (e) => {
  if (e.detail.topic !== "settings") return;
  applySiteLanguages(live.settings);
  if (loaded) render(); // an arrival waits for the site's language to be said in
});
conn.subscribe(["orders", "tasks", "settings"]);
calls?.start();
conn.start();
