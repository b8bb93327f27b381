// Menu (the owner's): the dishes New order offers, by category, with price and whether they
// are available tonight. A dish is added or changed with `create dish` (the server keeps one
// record per name); staff do not see this tab (the server refuses them anyway).

import { act, byName, el, KeyedList, toast } from "../ui.js";
import { onLangChange, t } from "../i18n.js";

function price(cents) {
  return cents === null || cents === undefined ? "" : (cents / 100).toFixed(2);
}

export class MenuPanel {
  constructor(root, conn, live) {
    this.conn = conn;
    this.live = live;
    this.name = el("input", { id: "menu-name", type: "text", maxlength: 64, required: true, autocomplete: "off" });
    this.category = el("input", { id: "menu-category", type: "text", maxlength: 64, list: "menu-categories", autocomplete: "off" });
    this.categories = el("datalist", { id: "menu-categories" });
    this.categoryOptions = new KeyedList(this.categories, { key: (c) => c, build: (c) => el("option", { value: c }) });
    this.price = el("input", { id: "menu-price", type: "number", min: 0, step: "0.01", inputmode: "decimal" });
    this.available = el("input", { id: "menu-available", type: "checkbox", checked: true });
    this.saveBtn = el("button", { type: "submit", class: "primary", "data-needs-online": true, "data-i18n": "menu.save" });
    const form = el(
      "form",
      { class: "menu-form", "data-i18n-aria-label": "menu.form" },
      el("label", { for: "menu-name", "data-i18n": "menu.name" }),
      this.name,
      el("label", { for: "menu-category", "data-i18n": "menu.category" }),
      this.category,
      this.categories,
      el("label", { for: "menu-price", "data-i18n": "menu.price" }),
      this.price,
      el("label", { class: "check" }, this.available, el("span", { "data-i18n": "menu.available" })),
      el("div", { class: "form-buttons" }, el("button", { type: "reset", class: "secondary", "data-i18n": "menu.new" }), this.saveBtn),
    );
    form.addEventListener("submit", (e) => {
      e.preventDefault();
      this._save();
    });
    form.addEventListener("reset", () => {
      // after the browser's own reset of the fields
      setTimeout(() => {
        this.available.checked = true;
        this.name.focus();
      });
    });
    this.list = el("ul", { class: "dish-list menu-items", "data-i18n-aria-label": "menu.title" });
    root.append(
      el(
        "div",
        { class: "menu-grid" },
        el(
          "section",
          { class: "card", "aria-labelledby": "menu-form-title" },
          el("h2", { id: "menu-form-title", "data-i18n": "menu.form" }),
          el("p", { class: "muted", "data-i18n": "menu.note" }),
          form,
        ),
        el("section", { class: "card", "aria-labelledby": "menu-title" }, el("h2", { id: "menu-title", "data-i18n": "menu.title" }), this.list),
      ),
    );
    this.rows = new KeyedList(this.list, {
      key: (m) => m.dish,
      signature: (m) => [m.category, m.price_cents, m.available],
      build: (m) => this._row(m),
      empty: () => el("li", { class: "muted" }, t("order.noMenu")),
    });
    live.addEventListener("change", (e) => e.detail.topic === "menu" && this.render());
    onLangChange(() => {
      this.rows.invalidate();
      this.render();
    });
    this.render();
  }

  _items() {
    return [...this.live.menu.values()].sort(
      (a, b) => byName(a.category, b.category) || a.position - b.position || byName(a.dish, b.dish),
    );
  }

  render() {
    const items = this._items();
    this.rows.update(items);
    const cats = [...new Set(items.map((m) => m.category).filter(Boolean))].sort(byName);
    this.categoryOptions.update(cats);
  }

  _row(m) {
    return el(
      "li",
      { "data-dish": m.dish, class: m.available ? "" : "unavailable" },
      el("span", { class: "dish" }, m.dish),
      el("span", { class: "muted" }, m.category || t("menu.noCategory")),
      el("span", { class: "price" }, price(m.price_cents)),
      el("span", { class: "availability" }, m.available ? t("menu.isAvailable") : t("menu.notAvailable")),
      el("button", {
        class: "secondary",
        "aria-label": t("menu.editFor", { dish: m.dish }),
        text: t("menu.edit"),
        onclick: () => this._edit(m),
      }),
    );
  }

  _edit(m) {
    this.name.value = m.dish;
    this.category.value = m.category;
    this.price.value = price(m.price_cents);
    this.available.checked = m.available;
    this.name.focus();
  }

  async _save() {
    const name = this.name.value.trim();
    if (!name) return;
    const old = this.live.menu.get(name);
    const text = this.price.value.trim();
    const cents = text === "" ? null : Math.round(Number(text) * 100);
    if (cents !== null && (!Number.isFinite(cents) || cents < 0)) {
      this.price.focus();
      return;
    }
    const last = Math.max(0, ...[...this.live.menu.values()].map((m) => m.position));
    const msg = {
      clientmsg: "create",
      type: "dish",
      name,
      category: this.category.value.trim(),
      price_cents: cents,
      available: this.available.checked,
      position: old ? old.position : last + 1,
    };
    const reply = await act(this.saveBtn, () => this.conn.request(msg));
    if (!reply) return;
    toast(t(old ? "menu.changed" : "menu.added", { dish: name }));
    this.name.value = "";
    this.price.value = "";
    this.available.checked = true;
  }
}
