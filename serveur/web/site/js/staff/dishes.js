// What the console's panels share about dishes and trips: a dish written with its quantity and
// note, the trays of a loading robot, the Go button, and the dish steps (cooking, ready, void,
// edit). Each step names the status the screen shows: a dish that moved on meanwhile (another
// tablet, the kitchen) is refused `stale` and the refusal is shown, nothing changes.

import { act, confirmDialog, el } from "../ui.js";
import { t } from "../i18n.js";

/** "Laksa ×2 (no chilli)": dish names and notes are the restaurant's words, shown as written. */
export function dishLabel(order) {
  let text = order.dish;
  if (order.quantity > 1) text = t("dish.quantity", { dish: text, quantity: order.quantity });
  if (order.note) text = t("dish.withNote", { dish: text, note: order.note });
  if (order.special) text = t("dish.special", { dish: text });
  return text;
}

/**
 * What is on each tray of a trip: [{tray, table, orders: [{order, table}]}]. A dish is on the tray
 * staff chose for it (`order.tray`), else on its stop's (tray k: the stop of seq k-1); `table` is
 * the tray's one table, or null when staff put dishes of several tables on it.
 */
export function trayContents(live, taskId) {
  const trays = new Map();
  const tray = (n) => {
    if (!trays.has(n)) trays.set(n, { tray: n, tables: new Set(), orders: [] });
    return trays.get(n);
  };
  for (const stop of live.trays(taskId)) {
    if (!stop.orders.length) tray(stop.tray).tables.add(stop.table); // dishes still to come
    for (const order of stop.orders) {
      const on = tray(order.tray ?? stop.tray);
      on.tables.add(stop.table);
      on.orders.push({ order, table: stop.table });
    }
  }
  return [...trays.values()]
    .sort((a, b) => a.tray - b.tray)
    .map((x) => ({ tray: x.tray, table: x.tables.size === 1 ? [...x.tables][0] : null, orders: x.orders }));
}

/** The trays of a trip: "Tray 1 → T7: Laksa ×2 (no chilli), Satay", "Tray 2: Tea (T3), Soup (T5)". */
export function trayList(live, taskId) {
  return el(
    "ul",
    { class: "trays", "aria-label": t("loading.trays") },
    trayContents(live, taskId).map((tray) =>
      el(
        "li",
        { "data-tray": tray.tray },
        el("span", { class: "tray-no" }, tray.table ? t("loading.tray", { tray: tray.tray, table: tray.table }) : t("loading.trayMixed", { tray: tray.tray })),
        " ",
        el(
          "span",
          { class: "tray-dishes" },
          tray.orders.length
            ? tray.orders.map(({ order, table }) => (tray.table ? dishLabel(order) : t("loading.dishFor", { dish: dishLabel(order), table }))).join(", ")
            : "…",
        ),
      ),
    ),
  );
}

/** A signature of what trayList draws, so a view redraws only when it changed. */
export function traySignature(live, taskId) {
  return JSON.stringify(trayContents(live, taskId).map((tray) => [tray.tray, tray.table, tray.orders.map(({ order, table }) => [table, dishLabel(order)])]));
}

/** The big Go button of a robot loaded at the pass: it leaves on the trip this screen shows. */
export function goButton(conn, live, name) {
  return el("button", {
    class: "go big",
    "data-needs-online": true,
    "aria-label": t("loading.goFor", { name }),
    text: t("loading.go"),
    onclick: (e) => act(e.currentTarget, () => conn.request({ clientmsg: "go", robot: name, ...live.target(name) })),
  });
}

/** One step of a dish, naming the status this screen shows it in. */
export function dishStep(conn, button, order, action, extra = {}) {
  return act(button, () =>
    conn.request({ clientmsg: "dish", order: order.id, action, status: order.status, ...extra }),
  );
}

export async function voidDish(conn, button, order) {
  const yes = await confirmDialog(t("dish.voidQuestion", { dish: dishLabel(order), table: order.table }), {
    yes: t("dish.voidYes"),
    no: t("dish.voidNo"),
  });
  if (yes) await dishStep(conn, button, order, "void");
}

/** A small dialog to change a dish's quantity and note. */
export function editDish(conn, order) {
  const titleId = `edit-${order.id}`;
  const quantity = el("input", { type: "number", min: 1, max: 99, step: 1, value: order.quantity, required: true });
  const note = el("input", { type: "text", maxlength: 200, value: order.note || "", autocomplete: "off" });
  const save = el("button", { type: "submit", class: "primary", "data-needs-online": true, text: t("dish.save") });
  const cancel = el("button", { type: "button", class: "secondary", text: t("dish.cancel") });
  const form = el(
    "form",
    { class: "edit-dish" },
    el("h2", { id: titleId }, t("dish.editTitle", { dish: order.dish, table: order.table })),
    el("label", {}, el("span", {}, t("dish.quantityLabel")), quantity),
    el("label", {}, el("span", {}, t("dish.note")), note),
    el("div", { class: "dialog-buttons" }, cancel, save),
  );
  const dialog = el("dialog", { class: "confirm", "aria-labelledby": titleId }, form);
  const close = () => {
    dialog.close();
    dialog.remove();
  };
  cancel.addEventListener("click", close);
  dialog.addEventListener("cancel", (e) => {
    e.preventDefault();
    close();
  });
  form.addEventListener("submit", async (e) => {
    e.preventDefault();
    const q = Number(quantity.value);
    if (!Number.isInteger(q) || q < 1 || q > 99) {
      quantity.focus();
      return;
    }
    const reply = await dishStep(conn, save, order, "edit", { quantity: q, note: note.value.trim() });
    if (reply) close();
  });
  document.body.append(dialog);
  dialog.showModal();
  quantity.focus();
}

/** The buttons every editable dish has: edit (quantity, note) and void. */
export function editButtons(conn, order) {
  const label = dishLabel(order);
  return [
    el("button", {
      class: "secondary",
      "data-needs-online": true,
      "aria-label": t("dish.editFor", { dish: label, table: order.table }),
      text: t("dish.edit"),
      onclick: () => editDish(conn, order),
    }),
    el("button", {
      class: "danger",
      "data-needs-online": true,
      "aria-label": t("dish.voidFor", { dish: label, table: order.table }),
      text: t("dish.void"),
      onclick: (e) => voidDish(conn, e.currentTarget, order),
    }),
  ];
}
