// The robot status machine as the UI needs it: which instructions each status accepts
// (mirrors the allowed-actions table of docs/protocol.md) and how each status looks.
// The server still has the last word: a refused instruction comes back as an error and is shown.

const T = true;
const _ = false;
const ACTIONS = [
  "auto", "manual", "teleop", "initialpose", "goal", "goto",
  "ready", "next", "stop", "continue", "cancel", "save_waypoint", "go", "skip",
];
// prettier-ignore
const TABLE = {
  //          auto man tele init goal goto ready next stop cont canc save go skip
  Offline:    [_, _, _, _, _, _, _, _, _, _, _, _, _, _],
  Ready:      [T, T, _, _, _, _, _, _, _, _, _, T, _, _],
  Awaiting:   [_, _, _, _, _, _, T, _, _, _, _, T, _, _],
  Loading:    [_, T, _, _, _, _, _, _, _, _, T, T, T, _],
  Delivering: [_, _, _, _, _, _, _, _, T, _, _, T, _, _],
  Delivered:  [_, _, _, _, _, _, _, T, _, _, _, T, _, T],
  Stopped:    [_, _, _, _, _, _, _, _, _, T, T, T, _, T],
  Transit:    [_, _, _, _, _, _, _, _, T, _, _, T, _, _],
  Manual:     [_, _, T, T, T, T, T, _, _, _, _, T, _, _],
  Error:      [_, T, _, _, _, _, _, _, _, T, T, T, _, T],
};

export const STATUSES = Object.keys(TABLE);

export function allowed(status, action) {
  const row = TABLE[status];
  const i = ACTIONS.indexOf(action);
  return Boolean(row && i >= 0 && row[i]);
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
};

export function statusColour(status) {
  return STATUS_COLOURS[status] || "#555";
}
