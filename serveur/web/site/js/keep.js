// What a person was in the middle of, kept on this device across a reload (a tablet that
// slept, a page pulled down by mistake): the console's open tab, cart and new order's draft, the
// setup page's test trip. localStorage, so it also outlives the browser being closed; never
// anything the server owns — each page checks what it gets back against the live state.

/** The value kept under `key`, or `fallback` (none kept, unreadable, storage refused). */
export function kept(key, fallback = null) {
  try {
    const raw = window.localStorage.getItem(key);
    return raw === null ? fallback : JSON.parse(raw);
  } catch {
    return fallback;
  }
}

/** Keep `value` under `key` (null forgets it). A full or refused storage only loses the copy. */
export function keep(key, value) {
  try {
    if (value === null || value === undefined) window.localStorage.removeItem(key);
    else window.localStorage.setItem(key, JSON.stringify(value));
  } catch {
    // private mode or full: the work is still on screen, only not kept
  }
}
