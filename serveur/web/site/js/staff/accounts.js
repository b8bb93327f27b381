// Accounts (the owner's): people who log in, the tokens of the robots' and tables' screens and
// those of programs (programs.js), all through the protocol's `account` verb (the server refuses
// anyone but an owner).
// A password or a token is shown once, as the server returns it: it is never asked for again.
// Each screen's token comes with its setup link and a QR code (SVG from the server, shown as an
// image); the codes made since the tab was opened gather on a sheet the Print button prints.

import { act, byName, confirmDialog, el, formatTime, KeyedList, toast } from "../ui.js";
import { onLangChange, roleName, t } from "../i18n.js";
import { ProgramsSection } from "./programs.js";

const USER_ROLES = ["staff", "owner"];

function qrImage(svg, alt) {
  // An <img> of the SVG text: no markup of the reply enters the page's DOM (and the CSP allows
  // data: images only, never data: scripts).
  return el("img", { class: "qr", src: `data:image/svg+xml;charset=utf-8,${encodeURIComponent(svg)}`, alt });
}

function screenName(tok) {
  return tok.robot ? t("accounts.robotScreen", { name: tok.robot }) : t("accounts.tableScreen", { name: tok.table || "?" });
}

export class AccountsPanel {
  constructor(root, conn, live) {
    this.conn = conn;
    this.live = live;
    this.users = [];
    this.tokens = [];
    this.sheet = []; // {name, url, svg}: the QR codes made here, for the print sheet

    // -- people
    this.userName = el("input", { id: "acc-user", type: "text", maxlength: 64, required: true, autocomplete: "off" });
    this.userRole = el("select", { id: "acc-role" });
    this.addBtn = el("button", { type: "submit", class: "primary", "data-needs-online": true, "data-i18n": "accounts.add" });
    const addForm = el(
      "form",
      { class: "acc-form", "data-i18n-aria-label": "accounts.addTitle" },
      el("label", { for: "acc-user", "data-i18n": "accounts.name" }),
      this.userName,
      el("label", { for: "acc-role", "data-i18n": "accounts.role" }),
      this.userRole,
      el("div", { class: "form-buttons" }, this.addBtn),
    );
    addForm.addEventListener("submit", (e) => {
      e.preventDefault();
      this._addUser();
    });
    this.secret = el("div", { class: "acc-secret", role: "status", "data-testid": "password-shown" });
    this.userList = el("ul", { class: "acc-list", "data-i18n-aria-label": "accounts.people" });

    // -- screens
    this.kind = el("select", { id: "acc-kind" });
    this.target = el("select", { id: "acc-target" });
    // The robots or the tables, one option each: the one chosen stays while it exists.
    this.targets = new KeyedList(this.target, { key: (n) => n, build: (n) => el("option", { value: n, text: n }) });
    this.label = el("input", { id: "acc-label", type: "text", maxlength: 64, autocomplete: "off" });
    this.makeBtn = el("button", { type: "submit", class: "primary", "data-needs-online": true, "data-i18n": "accounts.makeToken" });
    this.allBtn = el("button", { type: "button", class: "secondary", "data-needs-online": true, "data-i18n": "accounts.allTables", onclick: () => this._allTables() });
    const tokenForm = el(
      "form",
      { class: "acc-form", "data-i18n-aria-label": "accounts.makeTitle" },
      el("label", { for: "acc-kind", "data-i18n": "accounts.kind" }),
      this.kind,
      el("label", { for: "acc-target", "data-i18n": "accounts.target" }),
      this.target,
      el("label", { for: "acc-label", "data-i18n": "accounts.label" }),
      this.label,
      el("div", { class: "form-buttons" }, this.allBtn, this.makeBtn),
    );
    tokenForm.addEventListener("submit", (e) => {
      e.preventDefault();
      this._makeToken();
    });
    this.kind.addEventListener("change", () => this._fillTargets());
    this.printBtn = el("button", { type: "button", class: "secondary", "data-i18n": "accounts.print", onclick: () => window.print(), disabled: true });
    this.made = el("div", { class: "acc-made", role: "status" });
    this.sheetList = el("ul", { class: "print-sheet", "data-i18n-aria-label": "accounts.sheet" });
    this.tokenList = el("ul", { class: "acc-list", "data-i18n-aria-label": "accounts.screens" });
    // -- programs (a till's bridge): their own card, fed from the same list of tokens
    this.programs = new ProgramsSection(conn, () => this.refresh());

    root.append(
      el(
        "div",
        { class: "acc-grid" },
        el(
          "section",
          { class: "card", "aria-labelledby": "acc-people-title" },
          el("h2", { id: "acc-people-title", "data-i18n": "accounts.people" }),
          el("h3", { "data-i18n": "accounts.addTitle" }),
          addForm,
          this.secret,
          this.userList,
        ),
        el(
          "section",
          { class: "card", "aria-labelledby": "acc-screens-title" },
          el("h2", { id: "acc-screens-title", "data-i18n": "accounts.screens" }),
          el("h3", { "data-i18n": "accounts.makeTitle" }),
          el("p", { class: "muted", "data-i18n": "accounts.makeNote" }),
          tokenForm,
          this.made,
          el("div", { class: "form-buttons" }, this.printBtn),
          this.tokenList,
        ),
        this.programs.section,
      ),
      this.sheetList,
    );
    live.addEventListener("change", (e) => ["robots", "waypoints"].includes(e.detail.topic) && this._fillTargets());
    const me = () => this.conn.session && this.conn.session.user;
    this.userRows = new KeyedList(this.userList, {
      key: (u) => u.name,
      signature: (u) => [u.role, u.name === me()],
      build: (u) => this._userRow(u, me()),
    });
    this.tokenRows = new KeyedList(this.tokenList, {
      key: (tok) => tok.id,
      signature: (tok) => [screenName(tok), tok.label, tok.last_used_at],
      build: (tok) => this._tokenRow(tok),
      empty: () => el("li", { class: "muted" }, t("accounts.noScreens")),
    });
    // A QR code made here never changes: printed as made.
    this.sheetRows = new KeyedList(this.sheetList, { key: (e) => e.url, build: (e) => this._sheetRow(e) });
    onLangChange(() => {
      for (const rows of [this.userRows, this.tokenRows, this.sheetRows]) rows.invalidate();
      this.programs.invalidate();
      this._render();
    });
    this._render();
  }

  /** Fetch the lists again (the tab was opened, or something changed). */
  async refresh() {
    try {
      const [users, tokens] = await Promise.all([
        this.conn.request({ clientmsg: "account", action: "list_users" }),
        this.conn.request({ clientmsg: "account", action: "list_tokens" }),
      ]);
      this.users = users.users;
      this.tokens = tokens.tokens.filter((tok) => tok.role === "robot-screen" || tok.role === "table-screen");
      this.programs.update(tokens.tokens.filter((tok) => tok.role === "integration"));
    } catch {
      return; // not an owner, or offline: the lists stay as they were
    }
    this._renderLists();
  }

  _render() {
    const role = this.userRole.value || "staff";
    this.userRole.replaceChildren(...USER_ROLES.map((r) => el("option", { value: r, text: roleName(r) })));
    this.userRole.value = role;
    const kind = this.kind.value || "table-screen";
    this.kind.replaceChildren(
      el("option", { value: "table-screen", text: t("accounts.kindTable") }),
      el("option", { value: "robot-screen", text: t("accounts.kindRobot") }),
    );
    this.kind.value = kind;
    this._fillTargets();
    this._renderLists();
    this._renderSheet();
  }

  _fillTargets() {
    const names =
      this.kind.value === "robot-screen"
        ? [...this.live.robots.keys()]
        : [...this.live.waypoints.values()].filter((w) => w.kind === "table").map((w) => w.name);
    names.sort(byName);
    this.targets.update(names);
  }

  _renderLists() {
    this.userRows.update(this.users);
    this.tokenRows.update(this.tokens);
  }

  _userRow(u, me) {
    const role = el("select", { "aria-label": t("accounts.roleOf", { name: u.name }), "data-needs-online": true });
    role.replaceChildren(...USER_ROLES.map((r) => el("option", { value: r, text: roleName(r) })));
    role.value = u.role;
    role.addEventListener("change", () => this._setRole(u, role));
    return el(
      "li",
      { "data-user": u.name },
      el("span", { class: "acc-name" }, u.name, u.name === me ? el("span", { class: "muted" }, ` ${t("accounts.you")}`) : null),
      role,
      el("button", {
        class: "secondary",
        "data-needs-online": true,
        "aria-label": t("accounts.resetFor", { name: u.name }),
        text: t("accounts.reset"),
        onclick: (e) => this._reset(u, e.currentTarget),
      }),
      el("button", {
        class: "danger",
        "data-needs-online": true,
        "aria-label": t("accounts.removeFor", { name: u.name }),
        text: t("accounts.remove"),
        onclick: (e) => this._remove(u, e.currentTarget),
      }),
    );
  }

  _tokenRow(tok) {
    return el(
      "li",
      { "data-token": tok.id },
      el("span", { class: "acc-name" }, screenName(tok)),
      el("span", { class: "muted" }, tok.label),
      el("span", { class: "muted" }, tok.last_used_at ? t("accounts.lastUsed", { time: formatTime(tok.last_used_at) }) : t("accounts.neverUsed")),
      el("button", {
        class: "danger",
        "data-needs-online": true,
        "aria-label": t("accounts.revokeFor", { name: screenName(tok), id: tok.id }),
        text: t("accounts.revoke"),
        onclick: (e) => this._revoke(tok, e.currentTarget),
      }),
    );
  }

  _showSecret(name, password) {
    this.secret.replaceChildren(
      el("p", {}, t("accounts.passwordFor", { name })),
      el("output", { class: "secret", "data-testid": "password" }, password),
      el("p", { class: "muted" }, t("accounts.shownOnce")),
    );
  }

  async _addUser() {
    const name = this.userName.value.trim();
    if (!name) return;
    const reply = await act(this.addBtn, () =>
      this.conn.request({ clientmsg: "account", action: "add_user", username: name, role: this.userRole.value }),
    );
    if (!reply) return;
    this.userName.value = "";
    this._showSecret(reply.user.name, reply.password);
    toast(t("accounts.added", { name: reply.user.name }));
    await this.refresh();
  }

  async _setRole(u, select) {
    const role = select.value;
    const yes = await confirmDialog(t("accounts.roleQuestion", { name: u.name, role: roleName(role) }), {
      detail: t("accounts.roleDetail"),
      yes: t("accounts.roleYes"),
    });
    if (!yes) {
      select.value = u.role;
      return;
    }
    const reply = await act(select, () => this.conn.request({ clientmsg: "account", action: "set_role", username: u.name, role }));
    if (!reply) select.value = u.role;
    await this.refresh();
  }

  async _reset(u, button) {
    const yes = await confirmDialog(t("accounts.resetQuestion", { name: u.name }), {
      detail: t("accounts.resetDetail"),
      yes: t("accounts.reset"),
    });
    if (!yes) return;
    const reply = await act(button, () => this.conn.request({ clientmsg: "account", action: "reset_password", username: u.name }));
    if (reply) this._showSecret(u.name, reply.password);
    await this.refresh();
  }

  async _remove(u, button) {
    const yes = await confirmDialog(t("accounts.removeQuestion", { name: u.name }), { yes: t("accounts.remove") });
    if (!yes) return;
    const reply = await act(button, () => this.conn.request({ clientmsg: "account", action: "remove_user", username: u.name }));
    if (reply) toast(t("accounts.removed", { name: u.name }));
    await this.refresh();
  }

  async _create(kind, name, label) {
    const msg = { clientmsg: "account", action: "create_token", role: kind, label, base: window.location.origin };
    msg[kind === "robot-screen" ? "robot" : "table"] = name;
    const reply = await this.conn.request(msg);
    // The restaurant's public address when the owner set it (the QR code holds it too), else
    // the one this page was opened at.
    const origin = (this.live.settings && this.live.settings.public_url) || window.location.origin;
    const entry = { name: screenName(reply.device), url: origin + reply.link, svg: reply.qr };
    this.sheet.push(entry);
    return entry;
  }

  _showMade(entries) {
    this.made.replaceChildren(
      el("p", { class: "muted" }, t("accounts.tokenShownOnce")),
      ...entries.map((e) =>
        el(
          "figure",
          { class: "acc-qr" },
          qrImage(e.svg, t("accounts.qrFor", { name: e.name })),
          el("figcaption", {}, el("strong", {}, e.name), el("br"), el("a", { href: e.url, class: "setup-link", target: "_blank", rel: "noopener" }, e.url)),
        ),
      ),
    );
    this._renderSheet();
  }

  async _makeToken() {
    const name = this.target.value;
    if (!name) return;
    const entry = await act(this.makeBtn, () => this._create(this.kind.value, name, this.label.value.trim()));
    if (!entry) return;
    this.label.value = "";
    this._showMade([entry]);
    await this.refresh();
  }

  async _allTables() {
    const tables = [...this.live.waypoints.values()].filter((w) => w.kind === "table").map((w) => w.name).sort(byName);
    if (!tables.length) return;
    const yes = await confirmDialog(t("accounts.allQuestion", { count: tables.length }), { yes: t("accounts.allYes") });
    if (!yes) return;
    const made = await act(this.allBtn, async () => {
      const out = [];
      for (const name of tables) out.push(await this._create("table-screen", name, ""));
      return out;
    });
    if (made) this._showMade(made);
    await this.refresh();
  }

  async _revoke(tok, button) {
    const yes = await confirmDialog(t("accounts.revokeQuestion", { name: screenName(tok) }), {
      detail: t("accounts.revokeDetail"),
      yes: t("accounts.revoke"),
    });
    if (!yes) return;
    const reply = await act(button, () => this.conn.request({ clientmsg: "account", action: "revoke_token", token: tok.id }));
    if (reply) toast(t("accounts.revoked", { name: screenName(tok) }));
    await this.refresh();
  }

  _renderSheet() {
    this.printBtn.disabled = this.sheet.length === 0;
    this.sheetRows.update(this.sheet);
  }

  _sheetRow(e) {
    return el("li", {}, qrImage(e.svg, t("accounts.qrFor", { name: e.name })), el("p", { class: "sheet-name" }, e.name), el("p", { class: "sheet-url" }, e.url));
  }
}
