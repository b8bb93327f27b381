// New order: pick a table and dishes; "Send to the pass" makes one `create order` per dish
// (each dish is an order, pending at the pass). Every line has its own client-made key, so
// sending again after a dropped connection never makes a dish twice.

import { act, byName, el, newKey, toast } from "../ui.js";

// A few quick picks; any dish can be typed.
const MENU = ["Laksa", "Satay", "Nasi lemak", "Rendang", "Roti canai", "Char kway teow", "Teh tarik", "Cendol"];

export class NewOrderPanel {
  constructor(root, conn, live) {
    this.conn = conn;
    this.live = live;
    this.table = null;
    this.lines = []; // {dish, table, key}
    this.tables = el("div", { class: "table-grid", role: "group", "aria-label": "Table" });
    this.dish = el("input", { id: "dish-name", type: "text", maxlength: 64, autocomplete: "off", placeholder: "Type a dish" });
    this.linesList = el("ul", { class: "order-lines", "aria-label": "Order" });
    this.sendBtn = el("button", { class: "primary big", onclick: () => this._send(), text: "Send to the pass" });
    const form = el(
      "form",
      { class: "dish-form" },
      el("label", { for: "dish-name" }, "Dish"),
      this.dish,
      el("button", { type: "submit", text: "Add dish" }),
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
        el("section", { class: "card", "aria-labelledby": "table-title" }, el("h2", { id: "table-title" }, "1. Table"), this.tables),
        el(
          "section",
          { class: "card", "aria-labelledby": "dishes-title" },
          el("h2", { id: "dishes-title" }, "2. Dishes"),
          el(
            "div",
            { class: "menu", role: "group", "aria-label": "Menu" },
            MENU.map((d) => el("button", { class: "secondary", "aria-label": `Add ${d}`, onclick: () => this._add(d), text: d })),
          ),
          form,
        ),
        el(
          "section",
          { class: "card", "aria-labelledby": "lines-title" },
          el("h2", { id: "lines-title" }, "3. Order"),
          this.linesList,
          this.sendBtn,
        ),
      ),
    );
    live.addEventListener("change", (e) => e.detail.topic === "waypoints" && this._renderTables());
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
          "aria-label": `Table ${n}`,
          onclick: () => this._pick(n),
          text: n,
        }),
      ),
    );
    if (!names.length) this.tables.append(el("p", { class: "muted" }, "No table waypoints yet."));
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
      toast("Pick a table first.", { kind: "error" });
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
            "aria-label": `Remove ${line.dish} for ${line.table}`,
            onclick: () => {
              this.lines = this.lines.filter((l) => l !== line);
              this._renderLines();
            },
            text: "Remove",
          }),
        ),
      ),
    );
    if (!this.lines.length) this.linesList.append(el("li", { class: "muted" }, "Pick a table, then dishes."));
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
    if (sent.length) toast(`Sent to the pass: ${sent.join(", ")}`);
    this._renderLines();
  }
}
