// The Restaurant tab's Wi-Fi call buttons: a button on a table (a Shelly, a Tasmota or an
// ESPHome device) that calls a waiter, the plates robot or the bill with one press, by asking
// the server for its address. Add one (`site add_button`: its name, table and kind): its full
// address, `<the restaurant's address>/call/<token>`, is shown ONCE, with a Copy button and how
// to set each kind of device up (a plain HTTP GET of that address); the list says when each was
// last pressed; Revoke ends a button's address (`site revoke_button`: the address then answers
// 404). There is no topic for buttons: the list is read (`site buttons`) when the tab opens and
// after each change.

import { act, byName, el, formatTime, KeyedList, toast } from "../../ui.js";
import { t } from "../../i18n.js";
import { field } from "../forms.js";
import { confirmRemove, rowButton } from "./form.js";
import { CALL_KINDS, kindWords } from "../callwords.js";

export class ButtonsSection {
  constructor(conn, live) {
    this.conn = conn;
    this.live = live;
    this.name = el("input", { id: "btn-name", type: "text", maxlength: 64, required: true, autocomplete: "off" });
    this.table = el("select", { id: "btn-table", required: true });
    this.kind = el("select", { id: "btn-kind" });
    this.addBtn = el("button", { type: "submit", class: "primary", "data-needs-online": true, "data-i18n": "owner.buttons.add" });
    const form = el(
      "form",
      { class: "rest-buttons-form", "data-i18n-aria-label": "owner.buttons.form" },
      field("btn-name", "owner.buttons.name", this.name),
      field("btn-table", "owner.buttons.table", this.table),
      field("btn-kind", "owner.buttons.kind", this.kind),
      el("div", { class: "form-buttons" }, this.addBtn),
    );
    form.addEventListener("submit", (e) => {
      e.preventDefault();
      if (form.reportValidity()) this._add();
    });
    this.made = el("div", { class: "btn-made", "data-testid": "button-made", hidden: true });
    this.list = el("ul", { class: "rest-list", "data-i18n-aria-label": "owner.buttons.list" });
    this.rows = new KeyedList(this.list, {
      key: (b) => b.name,
      signature: (b) => [b.table, b.kind, b.revoked_at, b.last_press],
      build: (b) => this._row(b),
      empty: () => el("li", { class: "muted", text: t("owner.buttons.none") }),
    });
    this.buttons = [];
    this.section = el(
      "section",
      { class: "card rest-buttons", "aria-labelledby": "rest-buttons-title" },
      el("h2", { id: "rest-buttons-title", "data-i18n": "owner.buttons.title" }),
      el("p", { class: "muted", "data-i18n": "owner.buttons.note" }),
      form,
      this.made,
      el("h3", { "data-i18n": "owner.buttons.list" }),
      this.list,
    );
    this.fillKinds();
    this.render();
  }

  /** The kinds' words (again after a language change), the choice kept. */
  fillKinds() {
    const was = this.kind.value || "waiter";
    this.kind.replaceChildren(...CALL_KINDS.map((k) => el("option", { value: k, text: kindWords(k) })));
    this.kind.value = was;
  }

  /** The tables offered (they come and go), the choice kept. */
  render() {
    const was = this.table.value;
    const tables = [...this.live.waypoints.values()].filter((w) => w.kind === "table").map((w) => w.name).sort(byName);
    if (tables.join("\n") !== [...this.table.options].map((o) => o.value).join("\n")) {
      this.table.replaceChildren(...tables.map((name) => el("option", { value: name, text: name })));
      if (tables.includes(was)) this.table.value = was;
    }
    this.rows.update(
      [...this.buttons].sort((a, b) => Number(Boolean(a.revoked_at)) - Number(Boolean(b.revoked_at)) || byName(a.name, b.name)),
    );
  }

  /** Read the buttons afresh (the tab was opened, or one changed). */
  async load() {
    try {
      const reply = await this.conn.request({ clientmsg: "site", action: "buttons" });
      this.buttons = reply.buttons || [];
      this.render();
    } catch {
      // Not the owner (the tab is not shown then), or offline: the list stays as it was.
    }
  }

  /** Where a device reaches this server: the owner's address setting, else this page's. */
  _base() {
    const url = this.live.settings && this.live.settings.public_url;
    return (url || window.location.origin).replace(/\/+$/, "");
  }

  async _add() {
    const msg = { clientmsg: "site", action: "add_button", name: this.name.value.trim(), table: this.table.value, kind: this.kind.value };
    const reply = await act(this.addBtn, () => this.conn.request(msg));
    if (!reply) return;
    this.name.value = "";
    this._showOnce(reply.button, this._base() + reply.path);
    toast(t("owner.buttons.added", { name: reply.button.name }));
    await this.load();
  }

  /** The new button's address, shown this once (the server keeps only a digest of it). */
  _showOnce(button, url) {
    const address = el("input", { id: "btn-url", type: "text", readonly: true, value: url, spellcheck: "false", class: "btn-url" });
    const copy = el("button", { type: "button", class: "secondary", "data-i18n": "owner.buttons.copy", onclick: () => this._copy(address) });
    const done = el("button", {
      type: "button",
      class: "secondary",
      "data-i18n": "owner.buttons.done",
      onclick: () => {
        this.made.hidden = true;
        this.made.replaceChildren();
        this.name.focus();
      },
    });
    this.made.replaceChildren(
      el("h3", { text: t("owner.buttons.madeTitle", { name: button.name, table: button.table }) }),
      el("p", { class: "rest-error", text: t("owner.buttons.once") }),
      field("btn-url", "owner.buttons.address", address),
      el("div", { class: "form-buttons" }, copy, done),
      el(
        "details",
        { class: "btn-howto" },
        el("summary", { "data-i18n": "owner.buttons.howTo" }),
        el("p", { text: t("owner.buttons.howGet") }),
        el(
          "ul",
          {},
          el("li", { text: t("owner.buttons.howShelly") }),
          el("li", { text: t("owner.buttons.howTasmota", { url }) }),
          el("li", { text: t("owner.buttons.howEsphome", { url }) }),
        ),
        el("p", { text: t("owner.buttons.howKind") }),
      ),
    );
    this.made.hidden = false;
    address.focus();
    address.select();
  }

  async _copy(input) {
    try {
      await navigator.clipboard.writeText(input.value);
    } catch {
      // No clipboard for a page over plain http on the restaurant's network: the old way.
      input.focus();
      input.select();
      if (!document.execCommand("copy")) {
        toast(t("owner.buttons.copyByHand"));
        return;
      }
    }
    toast(t("owner.buttons.copied"));
  }

  _row(b) {
    const pressed = b.last_press ? t("owner.buttons.lastPress", { time: formatTime(b.last_press) }) : t("owner.buttons.never");
    return el(
      "li",
      { class: b.revoked_at ? "rest-place revoked" : "rest-place", "data-button": b.name },
      el("span", { class: "rest-name", text: b.name }),
      el("span", { class: "rest-kind", text: t("owner.buttons.what", { table: b.table, kind: kindWords(b.kind) }) }),
      el("span", { class: "muted", text: b.revoked_at ? t("owner.buttons.revoked") : pressed }),
      b.revoked_at
        ? null
        : el(
            "div",
            { class: "row-actions" },
            rowButton(t("owner.buttons.revoke"), t("owner.buttons.revokeFor", { name: b.name }), (e) => this._revoke(b.name, e.currentTarget), { danger: true }),
          ),
    );
  }

  async _revoke(name, button) {
    const yes = await confirmRemove(button, {
      question: t("owner.buttons.revokeQuestion", { name }),
      detail: t("owner.buttons.revokeDetail"),
      yes: t("owner.buttons.revoke"),
      run: () => this.conn.request({ clientmsg: "site", action: "revoke_button", name }),
      done: t("owner.buttons.revokedName", { name }),
    });
    if (yes) await this.load();
  }
}
