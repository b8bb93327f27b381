// A table's screen: a robot standing at this table (which tray to take, its dishes, and a big
// "Food collected"), then the table's virtual cart — dishes on a robot and served
// (`order` {table}), plus the ones ready at the pass (the `orders` topic). The `tasks` topic
// brings only the trips with a stop at this table. URL: /table/<name> or ?table=<name>.
// Refreshed whenever an order or a trip of this table changes. A robot arriving here with food
// rings and says "Your food is here! Please take tray 1" once (sound.js); the footer's sound
// button mutes this screen.

import { Connection } from "./ws.js";
import { Live } from "./live.js";
import { act, el, KeyedList, showError, toast, watchConnection } from "./ui.js";
import { applySiteLanguages, dishLabel, lang, onLangChange, t } from "./i18n.js";
import { Announcer, muteButton, soundPrompt } from "./sound.js";

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
  signature: (here) => [here, here.orders.map((id) => order(id) && dishLabel(order(id)))],
  build: (here) => herePanel(here),
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

/** The robots standing at this table now: trips whose current stop is here and reached. */
function arrivals() {
  const out = [];
  for (const task of live.tasks.values()) {
    const stop = task.status === "active" ? task.stops[task.current_stop] : null;
    if (stop && stop.table === table && stop.status === "arrived" && task.robot) {
      out.push({ robot: task.robot, task: task.id, stop: stop.seq, orders: stop.orders });
    }
  }
  return out;
}

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
  if (reply) toast(t("guest.table.enjoy"));
}

function herePanel(here) {
  const tray = here.stop + 1; // tray k holds the dishes of the stop with seq k-1
  const labels = here.orders.map((id) => order(id)).map((o) => (o ? dishLabel(o) : t("robot.cartLoading")));
  return el(
    "section",
    { class: "here", "data-robot": here.robot },
    el("h2", { class: "here-title" }, t("guest.table.here")),
    el("p", { class: "take-tray" }, t("guest.takeTray", { tray })),
    el(
      "ul",
      { class: "here-dishes", "aria-label": t("guest.trayDishes", { tray }) },
      labels.map((label) => el("li", {}, label)),
    ),
    el("button", { class: "big collected", onclick: (e) => collected(e.currentTarget, here), text: t("robot.collected") }),
    el("p", { class: "hint" }, t("guest.table.collectedHint")),
  );
}

/** Each robot standing here with food: ring and say so, once per stop on this device. */
function announce(here) {
  if (!live.settings) return; // the site's settings choose the language: wait to speak it
  for (const h of here) {
    const words = t("guest.arrival.spoken", { tray: h.stop + 1 });
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
conn.start();
