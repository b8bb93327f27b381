// The centre's read-only API (serveur/hq/dashboard.py): a login gives a token, kept for this
// browser tab only (sessionStorage) and sent as `Authorization: Bearer <token>`; a 401 later
// means the login ended.

import { utcOffset } from "./format.js";

const TOKEN = "serveur.hq.token";
const NAME = "serveur.hq.name";

/** The centre refused the token: log in again. */
export class LoggedOut extends Error {}

/** The centre answered with an error (or did not answer). */
export class Failed extends Error {
  constructor(status, message) {
    super(message);
    this.status = status;
  }
}

function stored(key) {
  try {
    return window.sessionStorage.getItem(key);
  } catch {
    return null;
  }
}

let memory = { token: stored(TOKEN), name: stored(NAME) }; // storage may be disabled

export function session() {
  return memory.token ? { ...memory } : null;
}

export function forget() {
  memory = { token: null, name: null };
  try {
    window.sessionStorage.removeItem(TOKEN);
    window.sessionStorage.removeItem(NAME);
  } catch {
    /* storage disabled */
  }
}

/** Log in: true, or "wrong" (name or password) or "unreachable". */
export async function logIn(name, password) {
  let reply;
  try {
    reply = await fetch("/api/login", {
      method: "POST",
      headers: { "Content-Type": "application/json" },
      body: JSON.stringify({ name, password }),
      cache: "no-store",
    });
  } catch {
    return "unreachable";
  }
  if (reply.status === 401 || reply.status === 400) return "wrong";
  if (!reply.ok) return "unreachable";
  const body = await reply.json();
  memory = { token: body.token, name: body.name || name };
  try {
    window.sessionStorage.setItem(TOKEN, memory.token);
    window.sessionStorage.setItem(NAME, memory.name);
  } catch {
    /* storage disabled: the login lasts until the page is reloaded */
  }
  return true;
}

/** GET an API path with this device's UTC offset; its JSON. Throws LoggedOut or Failed. */
export async function get(path, params = {}) {
  const query = new URLSearchParams({ ...params, utc_offset: utcOffset() });
  let reply;
  try {
    reply = await fetch(`${path}?${query}`, {
      headers: { Authorization: `Bearer ${memory.token || ""}` },
      cache: "no-store",
    });
  } catch (err) {
    throw new Failed(0, String(err));
  }
  if (reply.status === 401) {
    forget();
    throw new LoggedOut();
  }
  if (!reply.ok) throw new Failed(reply.status, `HTTP ${reply.status}`);
  return reply.json();
}
