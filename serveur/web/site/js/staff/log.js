// Activity (the owner's): the audit trail, newest first — who did what, to what, from where, and
// whether the server did it or refused. Filtered by person, action, outcome and dates; "Load
// older" pages on with the last id shown (the `site audit` request's `before`). Read through
// the protocol's `site` verb with action `audit` (owners hold the audit scope).

import { act, el, formatTime, KeyedList } from "../ui.js";
import { onLangChange, roleName, t } from "../i18n.js";

const PAGE = 50;
const REFUSED = "refused"; // every outcome but ok: filtered here, the server matches exact codes

// What each instruction is, in an owner's words: by verb, then by action (create: by type).
const WHAT = {
  login: "owner.what.login",
  logout: "owner.what.logout",
  create: {
    order: "owner.what.createOrder",
    task: "owner.what.createTask",
    robot: "owner.what.createRobot",
    waypoint: "owner.what.createWaypoint",
    dish: "owner.what.createDish",
  },
  control: {
    auto: "owner.what.controlAuto",
    manual: "owner.what.controlManual",
    teleop: "owner.what.controlTeleop",
    initialpose: "owner.what.controlInitialpose",
    goal: "owner.what.controlGoal",
    goto: "owner.what.controlGoto",
  },
  ready: "owner.what.ready",
  next: "owner.what.next",
  stop: "owner.what.stop",
  continue: "owner.what.continue",
  cancel: "owner.what.cancel",
  go: "owner.what.go",
  skip: "owner.what.skip",
  dish: {
    cooking: "owner.what.dishCooking",
    ready: "owner.what.dishReady",
    void: "owner.what.dishVoid",
    edit: "owner.what.dishEdit",
  },
  ack: "owner.what.ack",
  clear: "owner.what.clear",
  account: {
    list_users: "owner.what.listUsers",
    add_user: "owner.what.addUser",
    set_role: "owner.what.setRole",
    reset_password: "owner.what.resetPassword",
    remove_user: "owner.what.removeUser",
    create_token: "owner.what.createToken",
    list_tokens: "owner.what.listTokens",
    revoke_token: "owner.what.revokeToken",
  },
  site: {
    edit_robot: "owner.what.editRobot",
    remove_robot: "owner.what.removeRobot",
    dependents: "owner.what.dependents",
    rename_waypoint: "owner.what.renameWaypoint",
    remove_waypoint: "owner.what.removeWaypoint",
    settings: "owner.what.settings",
    set_settings: "owner.what.setSettings",
    audit: "owner.what.audit",
  },
  stats: {
    figures: "owner.what.statsFigures",
    trips: "owner.what.statsTrips",
  },
};

// The action filter: the verbs, as the server records them.
const VERBS = {
  login: "owner.verb.login",
  logout: "owner.verb.logout",
  create: "owner.verb.create",
  control: "owner.verb.control",
  ready: "owner.verb.ready",
  go: "owner.verb.go",
  next: "owner.verb.next",
  skip: "owner.verb.skip",
  stop: "owner.verb.stop",
  continue: "owner.verb.continue",
  cancel: "owner.verb.cancel",
  dish: "owner.verb.dish",
  ack: "owner.verb.ack",
  clear: "owner.verb.clear",
  account: "owner.verb.account",
  site: "owner.verb.site",
  stats: "owner.verb.stats",
};

// Refusals an owner may meet, in words (any other code is shown as it is).
const OUTCOMES = {
  forbidden: "owner.outcome.forbidden",
  unauthorized: "owner.outcome.unauthorized",
  conflict: "owner.outcome.conflict",
  not_found: "owner.outcome.notFound",
  invalid_field: "owner.outcome.invalidField",
  stale: "owner.outcome.stale",
  rate_limited: "owner.outcome.rateLimited",
};

/** What the record says was done, in words. */
export function describeWhat(rec) {
  const data = rec.data || {};
  const sub = rec.verb === "create" ? data.type : data.action;
  const entry = Object.hasOwn(WHAT, rec.verb) ? WHAT[rec.verb] : null;
  const key = typeof entry === "string" ? entry : entry && sub && Object.hasOwn(entry, sub) ? entry[sub] : null;
  if (key) return t(key);
  return sub ? `${rec.verb} ${sub}` : rec.verb;
}

/** Who: "alice (owner)", "screen token 7 (table screen)", "nobody logged in". */
function describeWho(rec) {
  const [kind, id] = String(rec.actor).split(/:(.*)/s);
  const role = rec.role && rec.role !== "-" ? roleName(rec.role) : null;
  let who;
  if (kind === "user") who = id;
  else if (kind === "token") who = t("owner.log.token", { id });
  else if (rec.actor === "anonymous") who = t("owner.log.anonymous");
  else who = rec.actor;
  return role ? t("owner.log.whoRole", { who, role }) : who;
}

/** The target, with what the record adds: "T3", "T3 → Patio 3", "r1 (12.0, 3.5)". */
function describeTarget(rec) {
  const data = rec.data || {};
  const parts = [];
  if (rec.target) parts.push(rec.target);
  if (data.waypoint && data.waypoint !== rec.target) parts.push(data.waypoint);
  if (data.dish) parts.push(data.dish);
  if (Array.isArray(data.orders) && data.orders.length) parts.push(t("owner.log.orders", { ids: data.orders.join(", ") }));
  return parts.join(" · ");
}

function outcomeText(outcome) {
  if (outcome === "ok") return t("owner.log.ok");
  return t("owner.log.refused", { why: OUTCOMES[outcome] ? t(OUTCOMES[outcome]) : outcome });
}

/** A local day ("2026-11-24", from <input type=date>) as epoch seconds at its midnight. */
function dayStart(value, plusDays = 0) {
  const [y, m, d] = value.split("-").map(Number);
  return new Date(y, m - 1, d + plusDays).getTime() / 1000;
}

function when(epoch) {
  const date = new Date(epoch * 1000).toLocaleDateString(document.documentElement.lang || undefined, { day: "numeric", month: "short" });
  return `${date} ${formatTime(epoch)}`;
}

export class LogPanel {
  constructor(root, conn, live) {
    this.root = root;
    this.conn = conn;
    this.live = live;
    this.records = [];
    this.cursor = null; // the last id read: "Load older" asks for what is before it
    this.done = false; // nothing older

    this.person = el("input", { id: "log-person", type: "text", maxlength: 64, autocomplete: "off", list: "log-people", "data-i18n-placeholder": "owner.log.anyone" });
    this.people = el("datalist", { id: "log-people" });
    this.verb = el("select", { id: "log-verb" });
    this.outcome = el("select", { id: "log-outcome" });
    this.from = el("input", { id: "log-from", type: "date" });
    this.to = el("input", { id: "log-to", type: "date" });
    this.showBtn = el("button", { type: "submit", class: "primary", "data-needs-online": true, "data-i18n": "owner.log.show" });
    const form = el(
      "form",
      { class: "log-filters", "data-i18n-aria-label": "owner.log.filters" },
      el("div", { class: "rest-field" }, el("label", { for: "log-person", "data-i18n": "owner.log.person" }), this.person, this.people),
      el("div", { class: "rest-field" }, el("label", { for: "log-verb", "data-i18n": "owner.log.action" }), this.verb),
      el("div", { class: "rest-field" }, el("label", { for: "log-outcome", "data-i18n": "owner.log.outcome" }), this.outcome),
      el("div", { class: "rest-field" }, el("label", { for: "log-from", "data-i18n": "owner.log.from" }), this.from),
      el("div", { class: "rest-field" }, el("label", { for: "log-to", "data-i18n": "owner.log.to" }), this.to),
      el(
        "div",
        { class: "form-buttons" },
        el("button", { type: "reset", class: "secondary", "data-i18n": "owner.log.clear" }),
        this.showBtn,
      ),
    );
    form.addEventListener("submit", (e) => {
      e.preventDefault();
      this.load();
    });
    form.addEventListener("reset", () => setTimeout(() => this.load()));
    this.status = el("p", { class: "muted", role: "status" });
    this.list = el("ul", { class: "log-list", "data-i18n-aria-label": "owner.log.title" });
    // A record never changes: a row is built once (again after a language change); "Older"
    // adds rows below, a new search keeps the rows it finds again.
    this.rows = new KeyedList(this.list, { key: (rec) => rec.id, build: (rec) => this._row(rec) });
    this.olderBtn = el("button", { type: "button", class: "secondary", "data-needs-online": true, "data-i18n": "owner.log.older", hidden: true, onclick: () => this.loadOlder() });
    root.append(
      el(
        "section",
        { class: "card log-card", "aria-labelledby": "log-title" },
        el("h2", { id: "log-title", "data-i18n": "owner.log.title" }),
        el("p", { class: "muted", "data-i18n": "owner.log.note" }),
        form,
        this.status,
        this.list,
        el("div", { class: "form-buttons log-more" }, this.olderBtn),
      ),
    );
    onLangChange(() => {
      this._fillSelects();
      this.rows.invalidate();
      this._render();
    });
    this._fillSelects();
  }

  /** The tab was opened: the newest records, with the filters as they are. */
  shown() {
    this.load();
    this._fillPeople();
  }

  _fillSelects() {
    const verb = this.verb.value;
    this.verb.replaceChildren(
      el("option", { value: "", text: t("owner.log.anyAction") }),
      ...Object.entries(VERBS).map(([v, key]) => el("option", { value: v, text: t(key) })),
    );
    this.verb.value = verb;
    const outcome = this.outcome.value;
    this.outcome.replaceChildren(
      el("option", { value: "", text: t("owner.log.anyOutcome") }),
      el("option", { value: "ok", text: t("owner.log.ok") }),
      el("option", { value: REFUSED, text: t("owner.log.anyRefused") }),
      ...Object.entries(OUTCOMES).map(([v, key]) => el("option", { value: v, text: t("owner.log.refused", { why: t(key) }) })),
    );
    this.outcome.value = outcome;
  }

  async _fillPeople() {
    try {
      const reply = await this.conn.request({ clientmsg: "account", action: "list_users" });
      this.people.replaceChildren(...reply.users.map((u) => el("option", { value: u.name })));
    } catch {
      /* not an owner, or offline: type the name */
    }
  }

  _query() {
    const q = { clientmsg: "site", action: "audit", limit: PAGE };
    const person = this.person.value.trim();
    if (person) q.actor = person.includes(":") ? person : `user:${person}`;
    if (this.verb.value) q.verb = this.verb.value;
    if (this.outcome.value && this.outcome.value !== REFUSED) q.outcome = this.outcome.value;
    if (this.from.value) q.since = dayStart(this.from.value);
    if (this.to.value) q.until = dayStart(this.to.value, 1);
    return q;
  }

  /** One page (or, for "refused", pages until some refusals are found). */
  async _fetch(before) {
    const q = this._query();
    const refusedOnly = this.outcome.value === REFUSED;
    const found = [];
    let cursor = before;
    for (let round = 0; round < 10; round++) {
      const reply = await this.conn.request(cursor === null ? q : { ...q, before: cursor });
      const page = reply.audit;
      found.push(...(refusedOnly ? page.filter((a) => a.outcome !== "ok") : page));
      if (page.length) cursor = page[page.length - 1].id;
      if (page.length < PAGE) return { found, cursor, done: true };
      if (!refusedOnly || found.length >= PAGE / 2) break;
    }
    return { found, cursor, done: false };
  }

  async load() {
    const reply = await act(this.showBtn, () => this._fetch(null));
    if (!reply) return;
    this.records = reply.found;
    this.cursor = reply.cursor;
    this.done = reply.done;
    this._render();
  }

  async loadOlder() {
    if (this.done || this.cursor === null) return;
    const reply = await act(this.olderBtn, () => this._fetch(this.cursor));
    if (!reply) return;
    this.records.push(...reply.found);
    this.cursor = reply.cursor;
    this.done = reply.done;
    this._render();
    if (!reply.found.length) this.olderBtn.focus();
  }

  _render() {
    this.rows.update(this.records);
    this.status.textContent = this.records.length
      ? t(this.done ? "owner.log.countAll" : "owner.log.count", { count: this.records.length })
      : t("owner.log.none");
    this.olderBtn.hidden = this.done;
  }

  _row(rec) {
    const refused = rec.outcome !== "ok";
    return el(
      "li",
      { class: refused ? "log-row refused" : "log-row", "data-audit": rec.id },
      el("time", { class: "log-when", datetime: new Date(rec.ts * 1000).toISOString(), text: when(rec.ts) }),
      el("span", { class: "log-who", text: describeWho(rec) }),
      el("span", { class: "log-what", text: describeWhat(rec) }),
      el("span", { class: "log-target", text: describeTarget(rec) }),
      el("span", { class: "log-outcome", text: outcomeText(rec.outcome) }),
      rec.peer ? el("span", { class: "log-peer muted", text: t("owner.log.peer", { peer: rec.peer }) }) : null,
    );
  }
}

