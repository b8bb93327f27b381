// The page's one websocket to serveur (docs/protocol.md): requests matched to replies by id,
// topic snapshots and updates checked by seq, and reconnection with backoff.
//
// Events (an EventTarget): "state" {state: "connecting"|"online"|"offline", retryIn},
// "snapshot" {data} (a fresh {topic: snapshot} that replaces what the page has),
// "update" {topic, data}, "problem" {error} (something failed that no caller is awaiting),
// "login" {error} (credentials are needed: show the login form; `error` says why, or null),
// "session" {session} (logged in: who this page is).
//
// Authentication (docs/protocol.md "Authentication"): every connection starts with a `login`.
// The token is kept in localStorage: a session token from a password login (a shift long),
// or a screen's device token, given once in the address as `#token=...` (a fragment is never
// sent to the server nor written to its logs) and removed from the address at once.

import { t } from "./i18n.js";

const BACKOFF_MIN_MS = 250;
const BACKOFF_MAX_MS = 5000;
const REPLY_TIMEOUT_MS = 15000;
// Heartbeat: a `ping` every 2 s while online; nothing at all heard from the server for 5 s and
// the link is taken for dead (Wi-Fi stalled with the socket open, a tablet back from sleep):
// the page says so at once, refuses actions, and reconnects for a fresh snapshot. Wall time.
const HEARTBEAT_MS = 2000;
const SILENT_MS = 5000;

/** A refused or failed request: `code` is the protocol's error code (or a client-side one). */
export class ServerError extends Error {
  /**
   * `request`: the message it answers (ui.js words the error from it and `details`); `local`:
   * made by this page (offline, timeout...), its `message` already in the page's words.
   */
  constructor(code, message, details = null, { request = null, local = false } = {}) {
    super(message);
    this.name = "ServerError";
    this.code = code;
    this.details = details;
    this.request = request;
    this.local = local;
  }
}

/** An error this page made, its message already worded in the page's language. */
function localError(code, message) {
  return new ServerError(code, message, null, { local: true });
}

const TOKEN_KEY = "serveur.token";
const CLOSE_AUTH = 4001;

export function loadToken() {
  try {
    return window.localStorage.getItem(TOKEN_KEY);
  } catch {
    return null; // storage disabled: log in on every visit
  }
}

export function saveToken(token) {
  try {
    if (token) window.localStorage.setItem(TOKEN_KEY, token);
    else window.localStorage.removeItem(TOKEN_KEY);
  } catch {
    /* storage disabled */
  }
}

/** A `#token=...` in the address (a screen's setup link) is stored and wiped from the address. */
function adoptTokenFromAddress(loc = window.location) {
  const m = /(?:^#|&)token=([^&]+)/.exec(loc.hash);
  if (!m) return;
  saveToken(decodeURIComponent(m[1]));
  window.history.replaceState(null, "", loc.pathname + loc.search);
}

export function defaultUrl(loc = window.location) {
  const scheme = loc.protocol === "https:" ? "wss:" : "ws:";
  return `${scheme}//${loc.host}/ws`;
}

export class Connection extends EventTarget {
  constructor(url = defaultUrl()) {
    super();
    this.url = url;
    this.state = "connecting";
    this.topics = new Set();
    this._ws = null;
    this._nextId = 1;
    this._pending = new Map(); // id -> {msg, resolve, reject, resend, sent, timer}
    this._lastSeq = 0;
    this._attempt = 0;
    this._retryTimer = null;
    this.session = null;
    this._creds = null; // credentials typed in the login form, sent when the socket is open
    this._lastHeard = 0; // Date.now() of the last frame from the server
    this._beat = null; // the heartbeat timer while online
  }

  start() {
    adoptTokenFromAddress();
    this._open();
    return this;
  }

  /** Log in with {username, password} or {token} (from the login form). */
  login(creds) {
    this._creds = creds;
    if (this._ws && this._ws.readyState === WebSocket.OPEN) this._authenticate();
  }

  /** End the session here (and for good, for a password session); shows the login form. */
  async logout() {
    try {
      await this.request({ clientmsg: "logout" });
    } finally {
      saveToken(null);
      this.session = null;
      this._setState("connecting");
      this._emit("login", { error: null });
    }
  }

  _authenticate() {
    const creds = this._creds || (loadToken() ? { token: loadToken() } : null);
    this._creds = null;
    if (!creds) {
      this._emit("login", { error: null });
      return;
    }
    const id = this._nextId++;
    const entry = {
      msg: { clientmsg: "login", id, ...creds },
      resend: false,
      sent: false,
      timer: null,
      resolve: (reply) => {
        if (reply.session.token) saveToken(reply.session.token);
        this.session = reply.session;
        this._attempt = 0;
        this._lastSeq = 0; // seq counts per connection
        this._emit("session", { session: reply.session });
        this._setState("online");
        if (this.topics.size) this._sendData(this.topics);
        for (const e of this._pending.values()) if (!e.sent) this._send(e);
      },
      reject: (err) => {
        if (err.code === "connection_lost") return; // the reconnect logs in again
        if (err.code === "timeout") {
          if (this._ws) this._ws.close();
          return;
        }
        if (err.code === "unauthorized" && !creds.password) saveToken(null);
        this._emit("login", { error: err });
      },
    };
    entry.timer = setTimeout(() => {
      this._pending.delete(id);
      entry.reject(localError("timeout", t("error.timeout")));
    }, REPLY_TIMEOUT_MS);
    this._pending.set(id, entry);
    this._send(entry);
  }

  /** Subscribe to more topics; the reply's snapshot is emitted as a "snapshot" event. */
  subscribe(topics) {
    const fresh = topics.filter((t) => !this.topics.has(t));
    fresh.forEach((t) => this.topics.add(t));
    if (fresh.length && this.state === "online") this._sendData(fresh);
  }

  unsubscribe(topics) {
    const gone = topics.filter((t) => this.topics.delete(t));
    if (gone.length && this.state === "online") {
      this.request({ clientmsg: "data", topics: gone, unsubscribe: true }).catch((e) => this._problem(e));
    }
  }

  /**
   * Send one request; resolves with the `ok` reply, rejects with a ServerError.
   * `resend: true` is for requests that are safe to send twice (reads, keyed creates): they
   * wait for the connection and are sent again if it drops before the reply. Anything else
   * fails at once when offline, because the person must know it did not happen.
   */
  request(msg, { resend = false, timeout = REPLY_TIMEOUT_MS } = {}) {
    return new Promise((resolve, reject) => {
      if (this.state !== "online" && !resend) {
        reject(localError("offline", t("error.offline")));
        return;
      }
      const id = this._nextId++;
      const entry = { msg: { ...msg, id }, resolve, reject, resend, sent: false, timer: null };
      entry.timer = setTimeout(() => {
        this._pending.delete(id);
        reject(localError("timeout", t("error.timeout")));
      }, timeout);
      this._pending.set(id, entry);
      if (this.state === "online") this._send(entry);
    });
  }

  _send(entry) {
    const ws = this._ws;
    if (!ws || ws.readyState !== WebSocket.OPEN) {
      // The socket is going (the server closing it for a restart, the Wi-Fi gone) and its
      // "close" has not come yet: nothing is sent on it. A request safe to resend waits for the
      // next connection; any other is not confirmed, and the person must know it did not happen.
      if (!entry.resend) {
        clearTimeout(entry.timer);
        this._pending.delete(entry.msg.id);
        entry.reject(localError("connection_lost", t("error.connectionLost")));
      }
      return;
    }
    entry.sent = true;
    ws.send(JSON.stringify(entry.msg));
  }

  _heartbeat() {
    if (Date.now() - this._lastHeard > SILENT_MS) {
      this._lost();
      return;
    }
    this.request({ clientmsg: "ping" }, { timeout: SILENT_MS }).catch(() => {}); // any frame will do
  }

  /**
   * The link went silent: drop this socket without waiting for a closing handshake a dead path
   * never answers. A command in flight is reported as not confirmed and never sent again; if
   * its bytes do reach the server later, the trip and stop it names make a late one `stale`.
   */
  _lost() {
    const ws = this._ws;
    if (!ws) return;
    this._ws = null;
    ws.onopen = ws.onmessage = ws.onclose = ws.onerror = null;
    try {
      ws.close();
    } catch {
      /* already closing */
    }
    this.session = null;
    this._dropInFlight();
    this._scheduleRetry();
  }

  _sendData(topics) {
    this.request({ clientmsg: "data", topics: [...topics] }, { resend: true })
      .then((reply) => this._emit("snapshot", { data: reply.data }))
      .catch((e) => {
        this._problem(e);
        // One unknown robot's stream must not block every other topic: drop it and retry.
        const robot = e.code === "not_found" && e.details && e.details.robot;
        if (!robot) return;
        const streams = ["pose", "scan", "cloud"].map((kind) => `${kind}:${robot}`);
        const rest = [...topics].filter((t) => !streams.includes(t));
        for (const s of streams) this.topics.delete(s);
        if (rest.length && rest.length < [...topics].length) this._sendData(rest);
      });
  }

  _open() {
    this._setState("connecting");
    let ws;
    try {
      ws = new WebSocket(this.url);
    } catch (e) {
      this._problem(localError("offline", t("error.cannotOpen", { url: this.url, error: e.message })));
      this._scheduleRetry();
      return;
    }
    this._ws = ws;
    ws.binaryType = "arraybuffer"; // camera pictures (docs/protocol.md, "Camera frames")
    ws.onopen = () => this._authenticate(); // "online" once the server knows who we are
    ws.onmessage = (ev) => this._receive(ev.data);
    ws.onclose = (ev) => {
      if (this._ws !== ws) return;
      this._ws = null;
      // Session expired or revoked (not merely "too slow to log in"): forget the token.
      if (ev.code === CLOSE_AUTH && this.session) saveToken(null);
      this.session = null;
      this._dropInFlight();
      this._scheduleRetry();
    };
    // A failed connection also fires "close", which does the retry; nothing to add here.
    ws.onerror = () => {};
  }

  _dropInFlight() {
    for (const [id, entry] of this._pending) {
      if (!entry.sent) continue;
      if (entry.resend) {
        entry.sent = false; // sent again as soon as we are back
      } else {
        clearTimeout(entry.timer);
        this._pending.delete(id);
        entry.reject(localError("connection_lost", t("error.connectionLost")));
      }
    }
  }

  _scheduleRetry() {
    const base = Math.min(BACKOFF_MAX_MS, BACKOFF_MIN_MS * 2 ** this._attempt);
    const delay = Math.round(base * (0.75 + Math.random() * 0.5)); // jitter: tablets don't stampede
    this._attempt += 1;
    this._setState("offline", delay);
    clearTimeout(this._retryTimer);
    this._retryTimer = setTimeout(() => this._open(), delay);
  }

  _receive(text) {
    this._lastHeard = Date.now();
    if (text instanceof ArrayBuffer) {
      this._emit("camera", { buffer: text }); // the only binary message the server sends
      return;
    }
    let msg;
    try {
      msg = JSON.parse(text);
    } catch (e) {
      this._problem(localError("bad_json", t("error.badJson", { error: e.message })));
      return;
    }
    if (msg.servermsg === "update") {
      // seq is 1 for a connection's first update, so even a drop of the very first ones shows.
      const gap = msg.seq !== this._lastSeq + 1;
      this._lastSeq = msg.seq;
      this._emit("update", { topic: msg.topic, data: msg.data });
      // Updates were dropped for us: a fresh snapshot of everything replaces what we have.
      if (gap && this.topics.size) this._sendData(this.topics);
      return;
    }
    const entry = this._pending.get(msg.id);
    if (!entry) {
      if (msg.servermsg === "error") {
        this._problem(new ServerError(msg.code, msg.message, msg.details));
      }
      return;
    }
    this._pending.delete(msg.id);
    clearTimeout(entry.timer);
    if (msg.servermsg === "ok") entry.resolve(msg);
    else entry.reject(new ServerError(msg.code, msg.message, msg.details, { request: entry.msg }));
  }

  _setState(state, retryIn = 0) {
    this.state = state;
    clearInterval(this._beat);
    this._beat = null;
    if (state === "online") {
      this._lastHeard = Date.now();
      this._beat = setInterval(() => this._heartbeat(), HEARTBEAT_MS);
    }
    this._emit("state", { state, retryIn });
  }

  _problem(error) {
    this._emit("problem", { error });
  }

  _emit(type, detail) {
    this.dispatchEvent(new CustomEvent(type, { detail }));
  }
}
