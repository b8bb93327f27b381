// New order: pick a table and dishes from the menu (the `menu` topic: by category, dishes that
// ran out hidden), each with a quantity and a note for the kitchen, and may be a special
// delivery with a message (a birthday: special.js); "Send to the kitchen"
// makes one `create order` per line, status "ordered" (the kitchen marks it ready). Every line
// has its own client-made key, so sending again after a dropped connection never makes a dish
// twice.

import { act, byName, el, KeyedList, newKey, toast } from "../ui.js";
import { onLangChange, t } from "../i18n.js";
import { keep, kept } from "../keep.js";
import { specialControls, validSpecial } from "./special.js";

const DRAFT_KEY = "serveur.keep.order"; // the new order's draft, kept across a reload

/** A line read back from the kept draft, checked before use (storage is the device's). */
function validLine(l) {
  return (
    l && typeof l.dish === "string" && l.dish.trim() && typeof l.table === "string" &&
    Number.isInteger(l.quantity) && l.quantity >= 1 && l.quantity <= 99 &&
    typeof l.note === "string" && typeof l.key === "string" && validSpecial(l.special)
  );
}

export class NewOrderPanel {
  constructor(root, conn, live) {
    this.conn = conn;
    this.live = live;
    // The draft (the table picked, the lines with their keys) is kept across a reload: a line
    // sent just before it is not made twice (its key), and nothing typed is lost.
    const draft = kept(DRAFT_KEY);
    this.table = draft && typeof draft.table === "string" ? draft.table : null;
    this.lines = draft && Array.isArray(draft.lines) ? draft.lines.filter(validLine) : []; // {dish, table, quantity, note, key, qty}
    this.tables = el("div", { class: "table-grid", role: "group", "data-i18n-aria-label": "order.table" });
    this.menu = el("div", { class: "menu", role: "group", "data-i18n-aria-label": "order.menu" });
    this.dish = el("input", {
      id: "dish-name", type: "text", maxlength: 64, autocomplete: "off", "data-i18n-placeholder": "order.dishPlaceholder",
    });
    this.linesList = el("ul", { class: "order-lines", "data-i18n-aria-label": "order.order" });
    this.sendBtn = el("button", { class: "primary big", "data-needs-online": true, onclick: () => this._send(), "data-i18n": "order.send" });
    const form = el(
      "form",
      { class: "dish-form" },
      el("label", { for: "dish-name", "data-i18n": "order.dish" }),
      this.dish,
      el("button", { type: "submit", "data-i18n": "order.addDish" }),
    );
    form.addEventListener("submit", (e) => {
      e.preventDefault();
      this._add(this.dish.value);
      this.dish.value = "";
    });
    root.append(
      el(
        "div",
        { class: "order-grid" },
        el("section", { class: "card", "aria-labelledby": "table-title" }, el("h2", { id: "table-title", "data-i18n": "order.step1" }), this.tables),
        el(
          "section",
          { class: "card", "aria-labelledby": "dishes-title" },
          el("h2", { id: "dishes-title", "data-i18n": "order.step2" }),
          this.menu,
          form,
        ),
        el(
          "section",
          { class: "card", "aria-labelledby": "lines-title" },
          el("h2", { id: "lines-title", "data-i18n": "order.step3" }),
          this.linesList,
          this.sendBtn,
        ),
      ),
    );
    // The table buttons (the one picked is pressed: _pick), the menu's groups of dishes, and the
    // order's lines, which keep their nodes: a note being typed is not redrawn under the fingers.
    this.tableRows = new KeyedList(this.tables, {
      key: (n) => n,
      build: (n) => this._tableButton(n),
      empty: () => el("p", { class: "muted" }, t("order.noTables")),
    });
    this.menuRows = new KeyedList(this.menu, {
      key: ([category]) => category,
      signature: ([, dishes]) => dishes.map((m) => m.dish),
      build: ([category, dishes]) => this._menuGroup(category, dishes),
      empty: () => el("p", { class: "muted" }, t("order.noMenu")),
    });
    this.lineRows = new KeyedList(this.linesList, {
      key: (line) => line.key,
      build: (line) => this._lineNode(line),
      empty: () => el("li", { class: "muted" }, t("order.empty")),
    });
    live.addEventListener("change", (e) => {
      if (e.detail.topic === "waypoints") this._renderTables();
      if (e.detail.topic === "menu") this._renderMenu();
    });
    onLangChange(() => {
      for (const rows of [this.tableRows, this.menuRows, this.lineRows]) rows.invalidate(); // new words
      this._renderTables();
      this._renderMenu();
      this._renderLines();
    });
    this._renderTables();
    this._renderMenu();
    this._renderLines();
  }

  /** The menu by category (in menu order); dishes not available tonight are not offered. */
  _renderMenu() {
    const items = [...this.live.menu.values()]
      .filter((m) => m.available)
      .sort((a, b) => a.position - b.position || byName(a.dish, b.dish));
    const groups = new Map();
    for (const m of items) {
      if (!groups.has(m.category)) groups.set(m.category, []);
      groups.get(m.category).push(m);
    }
    this.menuRows.update([...groups]);
  }

  _menuGroup(category, dishes) {
    return el(
      "div",
      { class: "menu-group", role: "group", "aria-label": category || t("menu.noCategory") },
      el("h3", {}, category || t("menu.noCategory")),
      el(
        "div",
        { class: "menu-dishes" },
        dishes.map((m) =>
          el("button", {
            class: "secondary",
            "aria-label": t("order.addNamed", { dish: m.dish }),
            onclick: () => this._add(m.dish),
            text: m.dish,
          }),
        ),
      ),
    );
  }

  _renderTables() {
    const names = [...this.live.waypoints.values()].filter((w) => w.kind === "table").map((w) => w.name).sort(byName);
    this.tableRows.update(names);
  }

  _tableButton(n) {
    return el("button", {
      class: "table-btn",
      "aria-pressed": String(n === this.table),
      "aria-label": t("order.tableNamed", { table: n }),
      onclick: () => this._pick(n),
      text: n,
    });
  }

  /** Staff add a ticket's dishes by hand: its table picked when it is one, the dish's name next. */
  startFor(table) {
    if (table && this.live.waypoints.get(table)?.kind === "table") this._pick(table);
    this.dish.focus();
  }

  _keep() {
    const lines = this.lines.map(({ dish, table, quantity, note, key, special }) => ({ dish, table, quantity, note, key, special: special ?? null }));
    keep(DRAFT_KEY, this.table || lines.length ? { table: this.table, lines } : null);
  }

  _pick(name) {
    this.table = name;
    this._keep();
    for (const b of this.tables.querySelectorAll("button")) {
      b.setAttribute("aria-pressed", String(b.textContent === name));
    }
  }

  _add(dish) {
    const d = dish.trim();
    if (!d) return;
    if (!this.table) {
      toast(t("order.pickTable"), { kind: "error" });
      return;
    }
    // The same dish again for the same table, no note yet: one more of it.
    const same = this.lines.find((l) => l.dish === d && l.table === this.table && !l.note && l.special == null);
    if (same && same.quantity < 99) {
      same.quantity += 1;
      this._showQuantity(same);
      this._keep();
      return;
    }
    this.lines.push({ dish: d, table: this.table, quantity: 1, note: "", key: newKey("dish"), special: null });
    this._renderLines();
  }

  _showQuantity(line) {
    if (line.qty) line.qty.textContent = t("order.quantity", { quantity: line.quantity });
  }

  _lineNode(line) {
    const change = (by) => {
      line.quantity = Math.min(99, Math.max(1, line.quantity + by));
      this._showQuantity(line);
      this._keep();
    };
    line.qty = el("span", { class: "qty", "aria-live": "polite" });
    this._showQuantity(line);
    const note = el("input", {
      type: "text",
      class: "note",
      maxlength: 200,
      autocomplete: "off",
      value: line.note,
      "aria-label": t("order.noteFor", { dish: line.dish, table: line.table }),
      placeholder: t("order.notePlaceholder"),
    });
    note.addEventListener("input", () => {
      line.note = note.value;
      this._keep();
    });
    return el(
      "li",
      { class: "order-line" },
      el("span", { class: "dish" }, line.dish),
      el("span", { class: "table-tag" }, line.table),
      el(
        "span",
        { class: "stepper", role: "group", "aria-label": t("order.quantityFor", { dish: line.dish, table: line.table }) },
        el("button", { class: "secondary", type: "button", "aria-label": t("order.less", { dish: line.dish }), text: "−", onclick: () => change(-1) }),
        line.qty,
        el("button", { class: "secondary", type: "button", "aria-label": t("order.more", { dish: line.dish }), text: "+", onclick: () => change(1) }),
      ),
      el("button", {
        class: "secondary",
        "aria-label": t("order.removeFor", { dish: line.dish, table: line.table }),
        onclick: () => {
          this.lines = this.lines.filter((l) => l !== line);
          this._renderLines();
        },
        text: t("order.remove"),
      }),
      note,
      specialControls(line, () => this._keep()),
    );
  }

  _renderLines() {
    this._keep();
    this.lineRows.update(this.lines);
    this.sendBtn.disabled = !this.lines.length;
  }

  async _send() {
    const sent = [];
    // One line at a time, so a refusal stops there and the unsent lines stay on screen.
    for (const line of [...this.lines]) {
      if (line.special != null && !line.special.trim()) {
        // Ticked without a message: the robot would have nothing to show.
        toast(t("order.specialEmpty", { dish: line.dish, table: line.table }), { kind: "error" });
        line.specialInput?.focus();
        break;
      }
      const msg = {
        clientmsg: "create",
        type: "order",
        dish: line.dish,
        table: line.table,
        quantity: line.quantity,
        status: "ordered",
        key: line.key,
      };
      const note = line.note.trim();
      if (note) msg.note = note;
      if (line.special != null) msg.special = line.special.trim();
      const reply = await act(this.sendBtn, () => this.conn.request(msg, { resend: true }));
      if (!reply) break;
      this.lines = this.lines.filter((l) => l !== line);
      sent.push(line.quantity > 1 ? `${line.dish} ×${line.quantity} (${line.table})` : `${line.dish} (${line.table})`);
      this._renderLines();
    }
    if (sent.length) toast(t("order.sent", { dishes: sent.join(", ") }));
    this._renderLines();
  }
}
