// The Till section's "the till's names for your dishes": a till prints what its own menu calls
// an item ("NASI LEMAK AYAM"), which may not be how serveur's menu spells it. The owner imports
// the till's menu as a CSV file (`till import_menu` with its text: a column `till`, and
// optionally `dish`): each row is matched, or comes with the likeliest dishes of the menu to
// choose from (`till map`); and the names tickets printed that are on neither the menu nor the
// matches (`till unmapped`) are listed the same way. One row's model: {till, dish, suggestions}.

import { act, byName, el, KeyedList, toast } from "../../ui.js";
import { t } from "../../i18n.js";
import { field } from "../forms.js";

const MAX_CSV = 200000; // characters: the server's limit for one import
let picks = 0; // the "another dish" pickers made, for their labels' ids

export class MenuNames {
  constructor(conn, live) {
    this.conn = conn;
    this.live = live;
    this.imported = []; // the import's rows, as the server matched them
    this.unmapped = []; // names tickets printed that no dish matches
    this.file = el("input", { id: "till-menu-file", type: "file", accept: ".csv,text/csv,text/plain", required: true });
    this.importBtn = el("button", { type: "submit", class: "secondary", "data-needs-online": true, "data-i18n": "owner.till.import" });
    const form = el(
      "form",
      { class: "till-import", "data-i18n-aria-label": "owner.till.namesTitle" },
      field("till-menu-file", "owner.till.menuFile", this.file),
      el("div", { class: "form-buttons" }, this.importBtn),
    );
    form.addEventListener("submit", (e) => {
      e.preventDefault();
      if (form.reportValidity()) this._import();
    });
    const rows = (none) => ({
      key: (r) => r.till,
      signature: (r) => [r.dish, r.suggestions, this._menu()],
      build: (r) => this._row(r),
      empty: none ? () => el("li", { class: "muted", text: t(none) }) : null,
    });
    this.importList = el("ul", { class: "rest-list till-names", "data-i18n-aria-label": "owner.till.importedTitle" });
    this.importRows = new KeyedList(this.importList, rows(null));
    this.importTitle = el("h4", { "data-i18n": "owner.till.importedTitle", hidden: true });
    this.unmappedList = el("ul", { class: "rest-list till-names", "data-i18n-aria-label": "owner.till.unmappedTitle" });
    this.unmappedRows = new KeyedList(this.unmappedList, rows("owner.till.noUnmapped"));
    this.section = el(
      "div",
      { class: "till-names-part", role: "group", "aria-labelledby": "rest-till-names-title" },
      el("h3", { id: "rest-till-names-title", "data-i18n": "owner.till.namesTitle" }),
      el("p", { class: "muted", "data-i18n": "owner.till.namesNote" }),
      form,
      this.importTitle,
      this.importList,
      el("h4", { "data-i18n": "owner.till.unmappedTitle" }),
      this.unmappedList,
    );
    live.addEventListener("change", (e) => e.detail.topic === "menu" && this._draw());
  }

  /** The names tickets printed that no dish matches, read afresh. */
  async load() {
    try {
      const reply = await this.conn.request({ clientmsg: "till", action: "unmapped" }, { resend: true });
      this.unmapped = reply.unmapped || [];
      this._draw();
    } catch {
      // Not the owner (the tab is not shown then), or offline: the list stays as it was.
    }
  }

  relabel() {
    this.importRows.invalidate();
    this.unmappedRows.invalidate();
    this._draw();
  }

  _draw() {
    this.importTitle.hidden = !this.imported.length;
    this.importRows.update(this.imported);
    this.unmappedRows.update(this.unmapped);
  }

  _menu() {
    return [...this.live.menu.keys()].sort(byName);
  }

  async _import() {
    const file = this.file.files[0];
    if (!file) return;
    const text = await file.text();
    if (text.length > MAX_CSV) {
      toast(t("owner.till.fileTooBig"), { kind: "error" });
      return;
    }
    const reply = await act(this.importBtn, () => this.conn.request({ clientmsg: "till", action: "import_menu", csv: text }));
    if (!reply) return;
    this.imported = (reply.rows || []).map((r) => ({ till: r.till, dish: r.status === "mapped" ? r.dish : null, suggestions: r.suggestions || [] }));
    const matched = this.imported.filter((r) => r.dish).length;
    toast(t("owner.till.imported", { count: this.imported.length, matched }));
    this._draw();
  }

  /** A till name: the dish it is, or the dishes it may be (and any dish of the menu). */
  _row(r) {
    const menu = this._menu();
    const head = el("span", { class: "rest-name", text: r.till });
    if (r.dish) {
      return el(
        "li",
        { class: "rest-place", "data-till-name": r.till },
        head,
        el("span", { class: "rest-kind", text: t("owner.till.isDish", { dish: r.dish }) }),
      );
    }
    const id = `till-name-${(picks += 1)}`;
    const other = el(
      "select",
      { id },
      el("option", { value: "", text: t("owner.till.pickDish") }),
      menu.map((dish) => el("option", { value: dish, text: dish })),
    );
    return el(
      "li",
      { class: "rest-place", "data-till-name": r.till },
      head,
      el("span", { class: "rest-kind", text: r.suggestions.length ? t("owner.till.maybe") : t("owner.till.notOnMenu") }),
      el(
        "div",
        { class: "row-actions till-suggestions" },
        r.suggestions.map((dish) =>
          el("button", {
            type: "button",
            class: "secondary",
            "data-needs-online": true,
            "aria-label": t("owner.till.matchFor", { till: r.till, dish }),
            text: dish,
            onclick: (e) => this._map(r, dish, e.currentTarget),
          }),
        ),
      ),
      el(
        "div",
        { class: "till-other" },
        el("label", { for: id, text: t("owner.till.otherDish", { till: r.till }) }),
        other,
        el("button", {
          type: "button",
          class: "secondary",
          "data-needs-online": true,
          "aria-label": t("owner.till.matchOtherFor", { till: r.till }),
          text: t("owner.till.match"),
          onclick: (e) => (other.value ? this._map(r, other.value, e.currentTarget) : other.focus()),
        }),
      ),
    );
  }

  async _map(row, dish, button) {
    const reply = await act(button, () => this.conn.request({ clientmsg: "till", action: "map", names: { [row.till]: dish } }));
    if (!reply) return;
    const names = reply.names || {};
    toast(t("owner.till.matched", { till: row.till, dish }));
    // Every row the mapping now names is matched; the names tickets printed are read again.
    this.imported = this.imported.map((r) => (names[r.till] ? { ...r, dish: names[r.till] } : r));
    this.unmapped = this.unmapped.filter((r) => !names[r.till]);
    this._draw();
    await this.load();
  }
}
