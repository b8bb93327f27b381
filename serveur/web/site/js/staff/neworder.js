// New order: pick a table and dishes; "Send to the pass" makes one `create order` per dish
// (each dish is an order, pending at the pass). Every line has its own client-made key, so
// sending again after a dropped connection never makes a dish twice.

import { act, byName, el, newKey, toast } from "../ui.js";
import { onLangChange, t } from "../i18n.js";

// A few quick picks; any dish can be typed. Dish names are the restaurant's data, not the
// page's words: they are sent and shown as written, in every language.
const MENU = ["Laksa", "Satay", "Nasi lemak", "Rendang", "Roti canai", "Char kway teow", "Teh tarik", "Cendol"];

export class NewOrderPanel {
  constructor(root, conn, live) {
    this.conn = conn;
    this.live = live;
    this.table = null;
    this.lines = []; // {dish, table, key}
    this.tables = el("div", { class: "table-grid", role: "group", "data-i18n-aria-label": "order.table" });
    this.dish = el("input", {
      id: "dish-name", type: "text", maxlength: 64, autocomplete: "off", "data-i18n-placeholder": "order.dishPlaceholder",
    });
    this.linesList = el("ul", { class: "order-lines", "data-i18n-aria-label": "order.order" });
    this.sendBtn = el("button", { class: "primary big", onclick: () => this._send(), "data-i18n": "order.send" });
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
          el(
            "div",
            { class: "menu", role: "group", "data-i18n-aria-label": "order.menu" },
            MENU.map((d) =>
              el("button", {
                class: "secondary",
                "data-i18n-aria-label": "order.addNamed",
                "data-i18n-args": { dish: d },
                onclick: () => this._add(d),
                text: d,
              }),
            ),
          ),
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
    live.addEventListener("change", (e) => e.detail.topic === "waypoints" && this._renderTables());
    onLangChange(() => {
      this._tablesShown = null; // same tables, new words
      this._renderTables();
      this._renderLines();
    });
    this._renderTables();
    this._renderLines();
  }

  _renderTables() {
    const names = [...this.live.waypoints.values()].filter((w) => w.kind === "table").map((w) => w.name).sort(byName);
    if (JSON.stringify(names) === this._tablesShown && names.includes(this.table)) return;
    this._tablesShown = JSON.stringify(names);
    this.tables.replaceChildren(
      ...names.map((n) =>
        el("button", {
          class: "table-btn",
          "aria-pressed": String(n === this.table),
          "aria-label": t("order.tableNamed", { table: n }),
          onclick: () => this._pick(n),
          text: n,
        }),
      ),
    );
    if (!names.length) this.tables.append(el("p", { class: "muted" }, t("order.noTables")));
  }

  _pick(name) {
    this.table = name;
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
    this.lines.push({ dish: d, table: this.table, key: newKey("dish") });
    this._renderLines();
  }

  _renderLines() {
    this.linesList.replaceChildren(
      ...this.lines.map((line) =>
        el(
          "li",
          {},
          el("span", { class: "dish" }, line.dish),
          el("span", { class: "table-tag" }, line.table),
          el("button", {
            class: "secondary",
            "aria-label": t("order.removeFor", { dish: line.dish, table: line.table }),
            onclick: () => {
              this.lines = this.lines.filter((l) => l !== line);
              this._renderLines();
            },
            text: t("order.remove"),
          }),
        ),
      ),
    );
    if (!this.lines.length) this.linesList.append(el("li", { class: "muted" }, t("order.empty")));
    this.sendBtn.disabled = !this.lines.length;
  }

  async _send() {
    const sent = [];
    // One line at a time, so a refusal stops there and the unsent lines stay on screen.
    for (const line of [...this.lines]) {
      const msg = { clientmsg: "create", type: "order", dish: line.dish, table: line.table, key: line.key };
      const reply = await act(this.sendBtn, () => this.conn.request(msg, { resend: true }));
      if (!reply) break;
      this.lines = this.lines.filter((l) => l !== line);
      sent.push(`${line.dish} (${line.table})`);
      this._renderLines();
    }
    if (sent.length) toast(t("order.sent", { dishes: sent.join(", ") }));
    this._renderLines();
  }
}
