// Programs (the owner's, in the Accounts tab): a token for a program that talks to serveur, such
// as the till's bridge posting orders to the order-intake API (docs/till.md, "For integrators").
// `account create_token` with role `integration`, a label and its scopes: here only "sends
// orders" (`orders`, the default) and "reads the restaurant" (`read`) are offered; a token made
// on the command line with other scopes is listed with them in words. The token is shown once,
// as the server returns it (no setup link, no QR code: it goes into the program's settings);
// the list says what each program may do and when it was last used, and Revoke ends it.

import { act, confirmDialog, el, formatTime, KeyedList, toast } from "../ui.js";
import { lang, t } from "../i18n.js";

// What a program may do, in the owner's words, in the order they are listed. The console offers
// the first two; the others only come from `serveur token create`.
const SCOPE_WORDS = {
  orders: "accounts.program.scope.orders",
  read: "accounts.program.scope.read",
  tasks: "accounts.program.scope.tasks",
  control: "accounts.program.scope.control",
  waypoints: "accounts.program.scope.waypoints",
  robots: "accounts.program.scope.robots",
  menu: "accounts.program.scope.menu",
  site: "accounts.program.scope.site",
  stats: "accounts.program.scope.stats",
  audit: "accounts.program.scope.audit",
};
const LOCALE = { en: "en", zh: "zh-Hans", ms: "ms" };

/** What a program's token lets it do: "sends orders and reads the restaurant". */
export function mayDo(scopes) {
  const known = Object.keys(SCOPE_WORDS).filter((s) => scopes.includes(s));
  const words = [...known.map((s) => t(SCOPE_WORDS[s])), ...scopes.filter((s) => !(s in SCOPE_WORDS))];
  try {
    return new Intl.ListFormat(LOCALE[lang()] || "en", { type: "conjunction" }).format(words);
  } catch {
    return words.join(", ");
  }
}

function programName(tok) {
  return tok.label || t("accounts.program.unnamed", { id: tok.id });
}

export class ProgramsSection {
  /** `refresh`: fetch the tokens again (the Accounts tab's), after one is made or revoked. */
  constructor(conn, refresh) {
    this.conn = conn;
    this.refresh = refresh;
    this.name = el("input", { id: "prog-label", type: "text", maxlength: 64, required: true, autocomplete: "off", spellcheck: "false" });
    this.orders = el("input", { id: "prog-orders", type: "checkbox", value: "orders", checked: true });
    this.read = el("input", { id: "prog-read", type: "checkbox", value: "read" });
    for (const box of [this.orders, this.read]) box.addEventListener("change", () => this.orders.setCustomValidity(""));
    this.createBtn = el("button", { type: "submit", class: "primary", "data-needs-online": true, "data-i18n": "accounts.program.create" });
    const form = el(
      "form",
      { class: "acc-form prog-form", "data-i18n-aria-label": "accounts.program.title" },
      el("label", { for: "prog-label", "data-i18n": "accounts.program.label" }),
      this.name,
      el(
        "fieldset",
        { class: "prog-may" },
        el("legend", { "data-i18n": "accounts.program.may" }),
        el("label", { class: "check", for: "prog-orders" }, this.orders, el("span", { "data-i18n": "accounts.program.orders" })),
        el("label", { class: "check", for: "prog-read" }, this.read, el("span", { "data-i18n": "accounts.program.read" })),
      ),
      el("div", { class: "form-buttons" }, this.createBtn),
    );
    form.addEventListener("submit", (e) => {
      e.preventDefault();
      this._create(form);
    });
    this.made = el("div", { class: "prog-made", "data-testid": "program-made", hidden: true });
    this.list = el("ul", { class: "acc-list", "data-i18n-aria-label": "accounts.program.list" });
    this.rows = new KeyedList(this.list, {
      key: (tok) => tok.id,
      signature: (tok) => [tok.label, tok.scopes.join(" "), tok.last_used_at],
      build: (tok) => this._row(tok),
      empty: () => el("li", { class: "muted", text: t("accounts.program.none") }),
    });
    this.tokens = [];
    this.section = el(
      "section",
      { class: "card", "aria-labelledby": "acc-programs-title" },
      el("h2", { id: "acc-programs-title", "data-i18n": "accounts.program.list" }),
      el("h3", { "data-i18n": "accounts.program.title" }),
      el("p", { class: "muted", "data-i18n": "accounts.program.note" }),
      form,
      this.made,
      this.list,
    );
  }

  /** The integration tokens, as `list_tokens` gave them. */
  update(tokens) {
    this.tokens = tokens;
    this.rows.update(tokens);
  }

  /** The language changed: every row is worded again. */
  invalidate() {
    this.rows.invalidate();
    this.rows.update(this.tokens);
  }

  async _create(form) {
    const scopes = [this.orders, this.read].filter((b) => b.checked).map((b) => b.value);
    this.orders.setCustomValidity(scopes.length ? "" : t("accounts.program.pickOne"));
    if (!form.reportValidity()) return;
    const label = this.name.value.trim();
    const msg = { clientmsg: "account", action: "create_token", role: "integration", scopes, label };
    const reply = await act(this.createBtn, () => this.conn.request(msg));
    if (!reply) return;
    this.name.value = "";
    this._showOnce(programName(reply.device), reply.token, scopes.includes("orders"));
    await this.refresh();
  }

  /** The token, this once (the server keeps only its digest), ready to copy. */
  _showOnce(name, token, sendsOrders) {
    const box = el("input", { id: "prog-token", type: "text", readonly: true, value: token, spellcheck: "false", autocomplete: "off", class: "prog-token" });
    const copy = el("button", { type: "button", class: "primary", "data-i18n": "accounts.program.copy", onclick: () => this._copy(box) });
    const done = el("button", {
      type: "button",
      class: "secondary",
      "data-i18n": "accounts.program.done",
      onclick: () => {
        this.made.hidden = true;
        this.made.replaceChildren();
        this.name.focus();
      },
    });
    this.made.replaceChildren(
      el("h3", { "data-i18n": "accounts.program.madeFor", "data-i18n-args": { name } }),
      el("p", { class: "prog-once", "data-i18n": "accounts.program.once" }),
      el("label", { for: "prog-token", "data-i18n": "accounts.program.token" }),
      box,
      el("div", { class: "form-buttons" }, copy, done),
      sendsOrders ? el("p", { class: "muted", "data-i18n": "accounts.program.where" }) : null,
    );
    this.made.hidden = false;
    box.focus();
    box.select();
  }

  async _copy(box) {
    try {
      await navigator.clipboard.writeText(box.value);
    } catch {
      // No clipboard for a page over plain http on the restaurant's network: the old way.
      box.focus();
      box.select();
      if (!document.execCommand("copy")) {
        toast(t("accounts.program.copyByHand"));
        return;
      }
    }
    toast(t("accounts.program.copied"));
  }

  _row(tok) {
    const name = programName(tok);
    return el(
      "li",
      { "data-token": tok.id },
      el("span", { class: "acc-name", text: name }),
      el("span", { class: "prog-can", text: mayDo(tok.scopes || []) }),
      el("span", { class: "muted", text: tok.last_used_at ? t("accounts.lastUsed", { time: formatTime(tok.last_used_at) }) : t("accounts.neverUsed") }),
      el("button", {
        class: "danger",
        "data-needs-online": true,
        "aria-label": t("accounts.revokeFor", { name, id: tok.id }),
        text: t("accounts.revoke"),
        onclick: (e) => this._revoke(tok, name, e.currentTarget),
      }),
    );
  }

  async _revoke(tok, name, button) {
    const yes = await confirmDialog(t("accounts.program.revokeQuestion", { name }), {
      detail: t("accounts.program.revokeDetail"),
      yes: t("accounts.revoke"),
    });
    if (!yes) return;
    const reply = await act(button, () => this.conn.request({ clientmsg: "account", action: "revoke_token", token: tok.id }));
    if (reply) toast(t("accounts.revoked", { name }));
    await this.refresh();
  }
}
