// The robot status machine as the UI needs it: which instructions each status accepts, and how
// each status looks. The table is the server's own (serveur/status.py ALLOWED), served as
// /js/status-table.js by serveur/web/static.py: no copy of it lives here.
// The server still has the last word: a refused instruction comes back as an error and is shown.

import { ALLOWED } from "./status-table.js";

const TABLE = new Map(Object.entries(ALLOWED).map(([status, actions]) => [status, new Set(actions)]));

export const STATUSES = [...TABLE.keys()];

export function allowed(status, action) {
  const row = TABLE.get(status);
  return Boolean(row && row.has(action));
}

// Colours are paired with the status word (i18n.js statusName: the wire value stays English)
// everywhere, so colour is never the only cue. Each reads at 4.5:1 or more both as white text on
// the colour (badges) and as the colour on the page's background (tests/web/test_a11y.py).
export const STATUS_COLOURS = {
  Offline: "#6a6e75",
  Ready: "#2d6bd2",
  Awaiting: "#117e53",
  Delivering: "#9e5f1f",
  Delivered: "#8e44ad",
  Stopped: "#c0392b",
  Transit: "#157a86",
  Manual: "#8e6708",
  Error: "#d9105c",
  Loading: "#6d4c41",
  Charging: "#556b2f",
};

export function statusColour(status) {
  return STATUS_COLOURS[status] || "#555";
}
