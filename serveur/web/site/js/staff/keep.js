// What staff were in the middle of, kept on this device across a reload (a tablet that slept,
// a page pulled down by mistake): the open tab, the cart at the pass, the new order's draft.
// localStorage, so it also outlives the browser being closed; never anything the server owns —
// each view checks what it gets back against the live state before using it.

const PREFIX = "serveur.keep.";

/** The value kept under `name`, or `fallback` (none kept, unreadable, storage refused). */
export function kept(name, fallback = null) {
  try {
    const raw = window.localStorage.getItem(PREFIX + name);
    return raw === null ? fallback : JSON.parse(raw);
  } catch {
    return fallback;
  }
}

/** Keep `value` under `name` (null forgets it). A full or refused storage only loses the copy. */
export function keep(name, value) {
  try {
    if (value === null || value === undefined) window.localStorage.removeItem(PREFIX + name);
    else window.localStorage.setItem(PREFIX + name, JSON.stringify(value));
  } catch {
    // private mode or full: the work is still on screen, only not kept
  }
}
