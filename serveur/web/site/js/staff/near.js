// A point of the floor in the words staff use: near which table or place, and which way it
// faces on the screen's map — never its coordinates ("(7.32, 5.00) facing 39°" told a waiter
// nothing; "near T5, facing right" does).

import { t } from "../i18n.js";

const CLOSE = 0.4; // metres: this near a place, the point is "at" it

/** The place nearest to (x, y) among `waypoints` (records with name, x, y), or null. */
function nearest(waypoints, x, y) {
  let best = null;
  let bestD = Infinity;
  for (const w of waypoints) {
    const d = Math.hypot(w.x - x, w.y - y);
    if (d < bestD) [best, bestD] = [w, d];
  }
  return best ? { name: best.name, d: bestD } : null;
}

/** "at T5", "about 1.5 m from T5", or "on the map" with no places yet. */
export function nearWords(waypoints, x, y) {
  const near = nearest(waypoints, x, y);
  if (!near) return t("near.onMap");
  if (near.d <= CLOSE) return t("near.at", { place: near.name });
  return t("near.from", { place: near.name, m: String(Math.max(0.5, Math.round(near.d * 2) / 2)) });
}

// The map is drawn with the floor's x to the right and y up: a heading is one of 8 screen ways.
const WAYS = ["near.facing.right", "near.facing.upRight", "near.facing.up", "near.facing.upLeft",
  "near.facing.left", "near.facing.downLeft", "near.facing.down", "near.facing.downRight"];

/** "facing up", "facing down-left"...: the heading `yaw` (radians) as the map shows it. */
export function facingWords(yaw) {
  const eighth = Math.round((((yaw % (2 * Math.PI)) + 2 * Math.PI) % (2 * Math.PI)) / (Math.PI / 4)) % 8;
  return t(WAYS[eighth]);
}

/** "at T5, facing up": where a spot chosen on the map is, for a toast or the keyboard hint. */
export function spotWords(waypoints, x, y, yaw) {
  const where = nearWords(waypoints, x, y);
  return yaw === null || yaw === undefined ? where : t("near.spot", { where, facing: facingWords(yaw) });
}
