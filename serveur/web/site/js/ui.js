// Small DOM helpers shared by every page: element building, toasts for errors and results,
// the connection banner, a confirmation dialog, and `act` to run a button's request.
// Every word shown comes from the catalogs (i18n.js): `data-i18n*` attributes given to `el`
// are applied at once and again after a language change.

import { onLangChange, t, translateNode } from "./i18n.js";
import { wordError } from "./errors.js";

// Whether the page is live. A control marked `data-needs-online` sends something to the server:
// while the connection is lost it is shown disabled (aria-disabled, so the page's own reasons
// to disable it are kept) and its clicks are refused here, and it comes back on reconnect.
let online = false;
const NEEDS_ONLINE = "[data-needs-online]";

function markOffline(node) {
  if (online) node.removeAttribute("aria-disabled");
  else node.setAttribute("aria-disabled", "true");
}

/** The connection's state drives every `data-needs-online` control of the page. */
export function guardOffline(conn) {
  const apply = () => {
    online = conn.state === "online";
    document.querySelectorAll(NEEDS_ONLINE).forEach(markOffline);
  };
  conn.addEventListener("state", apply);
  // Capture: the refusal comes before any handler of the button (mouse, touch or keyboard).
  document.addEventListener(
    "click",
    (e) => {
      if (online || !(e.target instanceof Element) || !e.target.closest(NEEDS_ONLINE)) return;
      e.preventDefault();
      e.stopImmediatePropagation();
      toast(t("error.offline"), { kind: "error" });
    },
    true,
  );
  apply();
}

/** el("button", {class: "big", onclick: f, "aria-label": "Stop r1"}, "Stop") */
export function el(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [key, value] of Object.entries(attrs)) {
    if (value === undefined || value === null || value === false) continue;
    if (key.startsWith("on")) node.addEventListener(key.slice(2), value);
    else if (key === "class") node.className = value;
    else if (key === "text") node.textContent = value;
    // CSSOM, not a style attribute: the Content-Security-Policy forbids inline style attributes.
    else if (key === "style") Object.assign(node.style, value);
    else if (key === "data-i18n-args") node.setAttribute(key, JSON.stringify(value));
    else if (value === true) node.setAttribute(key, "");
    else node.setAttribute(key, String(value));
  }
  for (const child of children.flat()) {
    if (child === null || child === undefined || child === false) continue;
    node.append(child instanceof Node ? child : document.createTextNode(String(child)));
  }
  if (Object.keys(attrs).some((k) => k.startsWith("data-i18n"))) translateNode(node);
  if (attrs["data-needs-online"]) markOffline(node);
  return node;
}

function toastRegion() {
  let region = document.getElementById("toasts");
  if (!region) {
    region = el("div", { id: "toasts", class: "toasts" });
    document.body.append(region);
  }
  return region;
}

const recent = new Map(); // message -> time shown, so a held joystick cannot flood the screen

/** Show a message; errors stay longer and are announced at once (role=alert). */
export function toast(message, { kind = "info", ms } = {}) {
  const now = performance.now();
  if (recent.has(message) && now - recent.get(message) < 3000) return;
  recent.set(message, now);
  const error = kind === "error";
  const close = el("button", { class: "toast-close", "data-i18n-aria-label": "toast.dismiss", text: "×" });
  const node = el(
    "div",
    { class: `toast toast-${kind}`, role: error ? "alert" : "status" },
    el("span", { class: "toast-text" }, message),
    close,
  );
  close.addEventListener("click", () => node.remove());
  toastRegion().append(node);
  setTimeout(() => node.remove(), ms ?? (error ? 12000 : 5000));
}

/**
 * A ServerError (or any error) as one sentence for the person in front of the screen, in the
 * page's language: this page's own (offline, timeout) as made; the server's worded from its code
 * and details (errors.js), never its English message, which goes to the console for whoever
 * integrates or debugs.
 */
export function describeError(err) {
  if (err && err.local) return err.message;
  if (err && err.code) {
    console.info(`serveur refused: ${err.code}: ${err.message}`, err.details || {});
    return wordError(err.code, err.details, err.request) ?? t("errors.unknown");
  }
  return t("error.other", { message: String((err && err.message) || err) });
}

export function showError(err) {
  toast(describeError(err), { kind: "error" });
}

/**
 * Run a request for a button: disable the button meanwhile, show the server's refusal if any.
 * Resolves with the reply, or null after showing the error — never throws, never hides.
 */
export async function act(button, makeRequest) {
  const hadFocus = Boolean(button) && document.activeElement === button;
  if (button) button.disabled = true;
  try {
    return await makeRequest();
  } catch (err) {
    showError(err);
    return null;
  } finally {
    if (button && button.isConnected) {
      button.disabled = false;
      // Disabling dropped the focus to <body>: give it back to the button pressed.
      const lost = !document.activeElement || document.activeElement === document.body;
      if (hadFocus && lost) button.focus();
    }
  }
}

/** Ask before an action that cannot be undone; resolves true only on the explicit "yes". */
export function confirmDialog(question, { yes = t("dialog.yes"), no = t("dialog.no"), detail = "" } = {}) {
  return new Promise((resolve) => {
    const titleId = `dlg-${Math.random().toString(36).slice(2)}`;
    const yesBtn = el("button", { class: "danger", text: yes });
    const noBtn = el("button", { class: "secondary", text: no });
    const dialog = el(
      "dialog",
      { class: "confirm", "aria-labelledby": titleId },
      el("h2", { id: titleId }, question),
      detail ? el("p", {}, detail) : null,
      el("div", { class: "dialog-buttons" }, noBtn, yesBtn),
    );
    const finish = (answer) => {
      dialog.close();
      dialog.remove();
      resolve(answer);
    };
    yesBtn.addEventListener("click", () => finish(true));
    noBtn.addEventListener("click", () => finish(false));
    dialog.addEventListener("cancel", (e) => {
      e.preventDefault(); // Escape means "no", through the same path
      finish(false);
    });
    document.body.append(dialog);
    dialog.showModal();
    noBtn.focus(); // the safe answer is the default
  });
}

/** The banner that says the page is not live, and the problems no button is waiting for. */
export function watchConnection(conn) {
  const banner = el("div", { class: "banner", role: "status", "aria-live": "polite", hidden: true });
  document.body.prepend(banner);
  let timer = null;
  let wasOnline = false; // once live, any reconnecting means what the page shows may be stale
  let last = null; // the last state event's detail, shown again in a new language
  const showState = ({ state, retryIn }) => {
    document.body.dataset.connection = state;
    clearInterval(timer);
    if (state === "online") {
      wasOnline = true;
      banner.hidden = true;
      banner.textContent = "";
      return;
    }
    banner.hidden = false;
    if (state === "connecting") {
      banner.textContent = wasOnline ? `${t("conn.lost")} ${t("conn.reconnecting")}` : t("conn.connecting");
      return;
    }
    const until = performance.now() + retryIn;
    const show = () => {
      const s = Math.max(0, Math.ceil((until - performance.now()) / 1000));
      banner.textContent = `${t("conn.lost")} ${s ? t("conn.reconnectingIn", { s }) : t("conn.reconnecting")}`;
    };
    show();
    timer = setInterval(show, 500);
  };
  conn.addEventListener("state", (e) => {
    last = { ...e.detail, at: performance.now() };
    showState(e.detail);
  });
  onLangChange(() => {
    if (!last || last.state === "online") return;
    showState({ state: last.state, retryIn: Math.max(0, last.retryIn - (performance.now() - last.at)) });
  });
  conn.addEventListener("problem", (e) => showError(e.detail.error));
  loginForm(conn);
}

/**
 * The login form, shown whenever the connection needs credentials: a person's user name and
 * password, or a device token (robot and table screens; usually given once by a
 * `#token=...` setup link instead).
 */
function loginForm(conn) {
  const why = el("p", { class: "login-why", role: "alert" });
  const user = el("input", { name: "username", autocomplete: "username", required: true });
  const pass = el("input", { name: "password", type: "password", autocomplete: "current-password", required: true });
  const token = el("input", { name: "token", autocomplete: "off", "data-i18n-placeholder": "login.tokenPlaceholder" });
  const form = el(
    "form",
    { class: "login", "data-i18n-aria-label": "login.form" },
    el("h2", { "data-i18n": "login.title" }),
    why,
    el("label", {}, el("span", { "data-i18n": "login.user" }), user),
    el("label", {}, el("span", { "data-i18n": "login.password" }), pass),
    el("button", { type: "submit", class: "primary", "data-i18n": "login.submit" }),
    el(
      "details",
      {},
      el("summary", { "data-i18n": "login.device" }),
      el("label", {}, el("span", { "data-i18n": "login.token" }), token),
      el("button", { type: "button", class: "use-token", "data-i18n": "login.useToken" }),
    ),
  );
  const dialog = el("dialog", { class: "login-dialog" }, form);
  document.body.append(dialog);
  dialog.addEventListener("cancel", (e) => e.preventDefault()); // no way around it but logging in
  form.addEventListener("submit", (e) => {
    e.preventDefault();
    why.textContent = t("login.busy");
    conn.login({ username: user.value.trim(), password: pass.value });
    pass.value = "";
  });
  form.querySelector(".use-token").addEventListener("click", () => {
    if (!token.value.trim()) return;
    why.textContent = t("login.busy");
    conn.login({ token: token.value.trim() });
    token.value = "";
  });
  conn.addEventListener("login", (e) => {
    const err = e.detail.error;
    why.textContent = !err
      ? ""
      : err.code === "unauthorized"
        ? t("login.wrong")
        : err.code === "rate_limited"
          ? t("login.rateLimited", { s: Math.ceil(err.details?.retry_after ?? 1) })
          : describeError(err);
    if (!dialog.open) dialog.showModal();
    (err && err.code !== "unauthorized" ? pass : user).focus();
  });
  conn.addEventListener("session", (e) => {
    document.body.dataset.role = e.detail.session.role;
    if (dialog.open) dialog.close();
    why.textContent = "";
  });
}

/** A stopwatch's reading: "2:10", "1:02:05". */
export function formatClock(seconds) {
  const s = Math.max(0, Math.floor(seconds));
  const mm = String(Math.floor(s / 60) % 60);
  const ss = String(s % 60).padStart(2, "0");
  return s >= 3600 ? `${Math.floor(s / 3600)}:${mm.padStart(2, "0")}:${ss}` : `${mm}:${ss}`;
}

/** A time of day on the server's clock (epoch s), written the page language's way. */
export function formatTime(epoch) {
  const locale = document.documentElement.lang || undefined;
  return new Date(epoch * 1000).toLocaleTimeString(locale, { hour: "2-digit", minute: "2-digit" });
}

export function formatDuration(seconds) {
  const s = Math.max(0, Math.floor(seconds));
  if (s < 60) return t("duration.s", { s });
  const m = Math.floor(s / 60);
  if (m < 60) return t("duration.ms", { m, s: String(s % 60).padStart(2, "0") });
  return t("duration.hm", { h: Math.floor(m / 60), m: String(m % 60).padStart(2, "0") });
}

/** A client-made key for idempotent creates. crypto.randomUUID needs https; this does not. */
export function newKey(prefix) {
  const bytes = crypto.getRandomValues(new Uint8Array(12));
  return `${prefix}-${Array.from(bytes, (b) => b.toString(16).padStart(2, "0")).join("")}`;
}

/** Natural order, so T2 comes before T10. */
export function byName(a, b) {
  return a.localeCompare(b, undefined, { numeric: true });
}

/**
 * A list drawn from records, keyed — the one way the pages draw a list that live updates change.
 * A row is built again only when its signature changed, rows that are gone are removed, and the
 * order follows the records; rows whose record did not change keep their node. So a tick or an
 * unrelated update does not replace a button under a finger, a note being typed or an open
 * <details>.
 *
 * A rebuilt row keeps the keyboard's place: when the focus was in the old row on a control marked
 * `data-focus-key`, the new row's control with the same key gets it (or, that one gone or
 * disabled, the row's first enabled `data-focus-key` control). `lostFocus(item)` may name the
 * key to focus in a rebuilt row when the focus had dropped to <body> (a button disabled while
 * its request runs loses it).
 *
 * Options: key(item) -> its key; signature(item) -> what the row shows (JSON-compared); build(item)
 * -> the row's node; empty() -> the node shown when there is nothing (optional).
 */
export class KeyedList {
  constructor(container, { key, signature = () => null, build, empty = null, lostFocus = null }) {
    this.container = container;
    this.key = key;
    this.signature = signature;
    this.build = build;
    this.empty = empty; // () => node shown when there is nothing
    this.lostFocus = lostFocus;
    this.rows = new Map(); // key -> {node, sig}
    this.emptyNode = null;
  }

  update(items) {
    const keep = new Set();
    if (items.length && this.emptyNode) {
      this.emptyNode.remove();
      this.emptyNode = null;
    }
    let prev = null;
    for (const item of items) {
      const k = this.key(item);
      keep.add(k);
      const sig = JSON.stringify(this.signature(item));
      let row = this.rows.get(k);
      if (!row || row.sig !== sig) {
        const focus = row ? this._focusKey(row.node, item) : null;
        const node = this.build(item);
        if (row) row.node.replaceWith(node);
        row = { node, sig };
        this.rows.set(k, row);
        if (focus) refocus(node, focus);
      }
      const want = prev ? prev.nextSibling : this.container.firstChild;
      if (want !== row.node) this.container.insertBefore(row.node, want);
      prev = row.node;
    }
    for (const [k, row] of this.rows) {
      if (!keep.has(k)) {
        row.node.remove();
        this.rows.delete(k);
      }
    }
    if (!items.length && this.empty) {
      const node = this.empty();
      if (this.emptyNode) this.emptyNode.replaceWith(node);
      else this.container.append(node);
      this.emptyNode = node;
    }
  }

  /** The node drawn for `key`, or null. */
  node(key) {
    const row = this.rows.get(key);
    return row ? row.node : null;
  }

  /** Same records, new words (a language change): every row is built again on the next update. */
  invalidate() {
    for (const row of this.rows.values()) row.sig = null;
  }

  /** Every row goes (another page of records, another range): the next update builds afresh. */
  clear() {
    for (const row of this.rows.values()) row.node.remove();
    this.rows.clear();
    if (this.emptyNode) this.emptyNode.remove();
    this.emptyNode = null;
  }

  _focusKey(old, item) {
    const active = document.activeElement;
    if (active && active !== document.body) return old.contains(active) ? active.dataset.focusKey || null : null;
    return this.lostFocus ? this.lostFocus(item) : null;
  }
}

/** Focus `row`'s control `key`, or its first enabled `data-focus-key` control when that one is
 *  gone or disabled. */
export function refocus(row, key) {
  const usable = (b) => b && !b.disabled;
  const same = row.querySelector(`[data-focus-key="${CSS.escape(key)}"]`);
  const target = usable(same) ? same : row.querySelector("[data-focus-key]:not(:disabled)");
  if (target) target.focus();
}
