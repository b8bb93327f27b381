// Where the map's words go, so that none covers another, a place's marker or a robot (issue 30,
// point 7: a robot's "→ T5" lay over table T1, which then read as T5).
//
// Pure: no canvas, no DOM. Given the labels wanted (each a text at an anchor point, with a
// priority) and what is drawn that a label must not hide (round things: place markers, robots,
// a destination's ring; rectangles: controls laid over the map), it says where each label goes.
// Widths come from the `measure(font, text)` it is given (the canvas's measureText in the page,
// an estimate in the Node test: tests/node/map_labels.mjs).
//
// The method is the standard greedy point-feature label placement, as in Christensen, Marks and
// Shieber, "An Empirical Study of Algorithms for Point-Feature Label Placement" (ACM Transactions
// on Graphics 14(3), 1995), whose greedy baseline and 8-position candidate model this is; MapLibre
// and Mapbox GL place their symbols the same way (text-variable-anchor and a collision index).
// Labels are taken in priority order, most important first (the view's order: table names, then
// robots with where they are going, then homes and the pass, then zones); each goes at the first
// of its candidate positions that hides nothing placed or drawn so far:
//   - the 8 positions around its anchor, right of it first (a name is read after its mark),
//     then the diagonals right, then left, then above and below;
//   - the same 8 a little further out, joined to the anchor by a leader line (the line may cross
//     no label and no marker, and no later label may cover it);
//   - then all of these again at a smaller size;
//   - for a label that must be shown (`keep`: tables' and robots' names), one repair step, in
//     the spirit of the paper's local improvements (labels moved one at a time): a position of
//     its own that hides no mark, blocked only by up to three labels placed already, each of
//     which can move to another free position of its own, is taken and they move (rows of
//     tables' names otherwise wall in a robot parked among them);
//   - then, for a label with a short form (a robot's: its name alone, without where it goes), the
//     short form at both sizes;
//   - and if still nothing is free, the label is left out. The label left out is always the
//     least important one so far, since they come in priority order: a more important label is
//     moved for a less important one, never shrunk or dropped.
// A label whose anchor is off the map's visible part (outside the canvas, or under a control laid
// over it) is not drawn: its mark is not seen either.
// A label's anchor grows to cover whatever is drawn on its mark (a robot parked on the table, the
// ring of a robot's destination: centred within the mark's radius), so its name sits beside
// them, not under.
// To keep names from jumping from side to side as a robot drives past, each ring tries first the
// position the same label had in the frame before (`previous`).

/** How far out each ring of candidates is, in CSS pixels from the anchor's edge. */
export const RINGS = [2, 10, 20, 32];
const SHRINK = 2; // px: the smaller size a label is tried at when nothing fits at its own
const MIN_SIZE = 9;
const MAX_MOVED = 3; // labels moved at most to make room for one

// The 8 positions, in the order tried: where the box's top-left corner goes, as
// (x + ax * R + bx * d + cx * w, y + ay * R + by * d + cy * h) for the anchor (x, y), its radius
// plus the ring's gap R, the diagonal's offset d = R / sqrt 2, the box's width w and height h.
const POSITIONS = [
  //  name  ax  bx  cx    ay  by  cy
  ["E", 1, 0, 0, 0, 0, -0.5],
  ["NE", 0, 1, 0, 0, -1, -1],
  ["SE", 0, 1, 0, 0, 1, 0],
  ["W", -1, 0, -1, 0, 0, -0.5],
  ["NW", 0, -1, -1, 0, -1, -1],
  ["SW", 0, -1, -1, 0, 1, 0],
  ["N", 0, 0, -0.5, -1, 0, -1],
  ["S", 0, 0, -0.5, 1, 0, 0],
].map(([name, axR, bxd, cxw, ayR, byd, cyh]) => ({ name, axR, bxd, cxw, ayR, byd, cyh }));
const BY_NAME = new Map(POSITIONS.map((p) => [p.name, p]));

/** The CSS font of a label at `size` px. */
export function fontOf(label, size) {
  return `${label.italic ? "italic " : ""}${label.bold ? "bold " : ""}${size}px system-ui, sans-serif`;
}

/**
 * Place the labels.
 *
 * @param wanted [{key, text, short, x, y, r, prio, size, bold, italic, pad, keep, kind, of, colour}]:
 *   the anchor (x, y) with the radius r of its mark, the priority (lower first; equal ones keep
 *   their order), the font size in px, `pad` the box's margin left and right of the text (px;
 *   default 1), `keep` to make room for it when nothing is free and `short` its short form
 *   (see above); kind, of (what it names) and colour are passed through.
 * @param scene {circles: [{x, y, r}], rects: [{x0, y0, x1, y1}], width, height}: what labels
 *   must not cover, and the visible area (0, 0)-(width, height).
 * @param measure (font, text) => width in px
 * @param previous Map key -> position name, from the last frame (or null)
 * @returns {placed, dropped, hidden}: placed [{key, text, kind, of, colour, x0, y0, x1, y1, font,
 *   size, pad, pos, ring, ax, ay, ar, leader: [x0, y0, x1, y1] or null}] (the box, the anchor and
 *   its grown radius), the keys left out, and the keys not visible.
 */
export function placeLabels(wanted, scene, measure, previous = null) {
  const { circles = [], rects = [], width, height } = scene;
  const world = { circles, rects, placed: [], width, height, measure };
  const dropped = [];
  const hidden = [];
  const todo = [];
  for (const [i, label] of wanted.entries()) {
    const { x, y } = label;
    if (!(x >= 0 && y >= 0 && x <= width && y <= height) || rects.some((b) => inRect(b, x, y))) {
      hidden.push(label.key);
      continue;
    }
    // The anchor grows over whatever is drawn on its mark.
    let ar = label.r;
    for (const c of circles) {
      const dx = c.x - x;
      const dy = c.y - y;
      const dd = dx * dx + dy * dy;
      if (dd < label.r * label.r) ar = Math.max(ar, Math.sqrt(dd) + c.r);
    }
    const was = (previous && BY_NAME.get(previous.get(label.key))) || null;
    todo.push({ label, i, ar, was, cands: new Map() });
  }
  todo.sort((a, b) => a.label.prio - b.label.prio || a.i - b.i);
  for (const t of todo) {
    const { label } = t;
    const sizes = label.size - SHRINK >= MIN_SIZE ? [label.size, label.size - SHRINK] : [label.size];
    const anywhere = (text) => {
      for (const size of sizes) {
        const spot = firstSpot(t, text, size, world);
        if (spot) return spot;
      }
      return null;
    };
    let spot = anywhere(label.text);
    if (!spot && label.keep) spot = makeRoom(t, world);
    // Shorter still: the label's short form (a robot's name without where it goes).
    if (!spot && label.short && label.short !== label.text) spot = anywhere(label.short);
    if (!spot) {
      dropped.push(label.key);
      continue;
    }
    world.placed.push(spot);
  }
  return { placed: world.placed, dropped, hidden };
}

/**
 * The positions of label `t` with `text` at `size` in ring `ring` that stay in view, in the order
 * tried: [{pos, ring, x0, y0, x1, y1, leader, fixed}...], `fixed` (hides no mark and no control)
 * worked out when first asked (fixedOk). Worked out once a frame for each label, and only for
 * the rings looked at.
 */
function ringOf(t, text, size, ring, world) {
  const key = `${size}\n${text}`;
  let c = t.cands.get(key);
  if (!c) {
    const { label, ar } = t;
    const { x, y } = label;
    const w = world.measure(fontOf(label, size), text) + 2 * (label.pad ?? 1);
    const h = size + 4; // a line of text and a pixel above and below (its halo)
    const reach = ar + RINGS[RINGS.length - 1] + w + h;
    const area = { x0: x - reach, y0: y - reach, x1: x + reach, y1: y + reach };
    const circles = world.circles.filter((k) => k.x + k.r > area.x0 && k.x - k.r < area.x1 && k.y + k.r > area.y0 && k.y - k.r < area.y1);
    c = { w, h, area, circles, rings: [] };
    t.cands.set(key, c);
  }
  if (!c.rings[ring]) {
    const { label, ar, was } = t;
    const { x, y } = label;
    const { w, h } = c;
    const R = ar + RINGS[ring];
    const d = R * Math.SQRT1_2;
    const found = [];
    for (const p of was ? [was, ...POSITIONS.filter((q) => q !== was)] : POSITIONS) {
      const x0 = x + p.axR * R + p.bxd * d + p.cxw * w;
      const y0 = y + p.ayR * R + p.byd * d + p.cyh * h;
      const b = { pos: p.name, ring, x0, y0, x1: x0 + w, y1: y0 + h, leader: null };
      if (x0 < 0 || y0 < 0 || b.x1 > world.width || b.y1 > world.height) continue;
      if (ring > 0) b.leader = leaderLine(x, y, ar, b);
      found.push(b);
    }
    c.rings[ring] = found;
  }
  return c.rings[ring];
}

/**
 * Label `t` with `text` at `size` at its first position (ring by ring) where nothing placed in
 * `world` is in the way: the placed label ({key, text, ..., leader, extent}), or null.
 */
function firstSpot(t, text, size, world) {
  ringOf(t, text, size, 0, world);
  const { area } = t.cands.get(`${size}\n${text}`);
  const placed = world.placed.filter((b) => overlap(b.extent, area));
  for (let ring = 0; ring < RINGS.length; ring++) {
    for (const c of ringOf(t, text, size, ring, world)) {
      if (!placed.some((b) => clash(b, c)) && fixedOk(t, text, size, c, world)) return spotOf(t, text, size, c);
    }
  }
  return null;
}

/** Whether candidate c hides no mark and no control (its box or its leader line), once. */
function fixedOk(t, text, size, c, world) {
  if (c.fixed === undefined) c.fixed = hitsNothingFixed(c, world.rects, t.cands.get(`${size}\n${text}`).circles);
  return c.fixed;
}

function spotOf(t, text, size, c) {
  const { label, ar } = t;
  const { key, kind, of, colour, prio } = label;
  const spot = { key, text, kind, of, colour, prio, x0: c.x0, y0: c.y0, x1: c.x1, y1: c.y1, font: fontOf(label, size), size, pad: label.pad ?? 1, pos: c.pos, ring: c.ring, ax: label.x, ay: label.y, ar, leader: c.leader };
  spot.extent = extent(spot);
  spot.entry = t;
  return spot;
}

/** Whether candidate c's box or leader line would hide one of the rects or circles. */
function hitsNothingFixed(c, rects, circles) {
  for (const r of rects) if (overlap(r, c) || (c.leader && segmentHitsBox(c.leader, r))) return false;
  for (const k of circles) if (circleHitsBox(k, c)) return false;
  if (c.leader) {
    const [sx, sy] = c.leader;
    for (const k of circles) {
      // The line starts on the anchor's edge: what is drawn on the anchor is no obstacle.
      const ox = k.x - sx;
      const oy = k.y - sy;
      if (ox * ox + oy * oy > (k.r + 0.5) ** 2 && segmentHitsCircle(c.leader, k)) return false;
    }
  }
  return true;
}

/** Whether two labels (box and leader line each) are in each other's way. */
function clash(a, b) {
  return overlap(a, b) || (a.leader && segmentHitsBox(a.leader, b)) || (b.leader && segmentHitsBox(b.leader, a));
}

/**
 * Room for a label nothing is free for (a robot's, walled in by tables' names): a position of
 * its own (at its size) that hides no mark or control, blocked only by up to MAX_MOVED labels
 * placed already, each of which can go to another free position of its own (at the size and in
 * the words it has). Then they move and it goes there; otherwise nothing changes. A more
 * important label is moved, never dropped or shrunk, for a less important one.
 */
function makeRoom(t, world) {
  const { label } = t;
  for (let ring = 0; ring < RINGS.length; ring++) {
    for (const c of ringOf(t, label.text, label.size, ring, world)) {
      if (!fixedOk(t, label.text, label.size, c, world)) continue;
      const blocking = world.placed.filter((p) => clash(p, c));
      if (blocking.length > MAX_MOVED) continue;
      const spot = spotOf(t, label.text, label.size, c);
      const trial = { ...world, placed: world.placed.filter((p) => !blocking.includes(p)).concat([spot]) };
      const moved = [];
      for (const b of blocking) {
        const again = firstSpot(b.entry, b.text, b.size, trial);
        if (!again) break;
        trial.placed.push(again);
        moved.push([b, again]);
      }
      if (moved.length < blocking.length) continue;
      for (const [b, again] of moved) world.placed[world.placed.indexOf(b)] = again;
      return spot;
    }
  }
  return null;
}

function extent(b) {
  if (!b.leader) return { x0: b.x0, y0: b.y0, x1: b.x1, y1: b.y1 };
  const [sx, sy, ex, ey] = b.leader;
  return { x0: Math.min(b.x0, sx, ex), y0: Math.min(b.y0, sy, ey), x1: Math.max(b.x1, sx, ex), y1: Math.max(b.y1, sy, ey) };
}

/** The line from the anchor's edge to the nearest point of the box. */
function leaderLine(x, y, r, box) {
  const bx = Math.max(box.x0, Math.min(x, box.x1));
  const by = Math.max(box.y0, Math.min(y, box.y1));
  const len = Math.hypot(bx - x, by - y) || 1;
  return [x + ((bx - x) / len) * r, y + ((by - y) / len) * r, bx, by];
}

export function overlap(a, b) {
  return a.x0 < b.x1 && b.x0 < a.x1 && a.y0 < b.y1 && b.y0 < a.y1;
}

function inRect(b, x, y) {
  return x >= b.x0 && x <= b.x1 && y >= b.y0 && y <= b.y1;
}

function circleHitsBox(c, b) {
  const dx = c.x - Math.max(b.x0, Math.min(c.x, b.x1));
  const dy = c.y - Math.max(b.y0, Math.min(c.y, b.y1));
  return dx * dx + dy * dy < c.r * c.r;
}

/** Whether segment [x0, y0, x1, y1] passes through the inside of box b (Liang-Barsky clipping). */
export function segmentHitsBox(s, b) {
  const x0 = s[0];
  const y0 = s[1];
  const dx = s[2] - x0;
  const dy = s[3] - y0;
  const t = [0, 1];
  return clip(-dx, x0 - b.x0, t) && clip(dx, b.x1 - x0, t) && clip(-dy, y0 - b.y0, t) && clip(dy, b.y1 - y0, t);
}

// One side of Liang-Barsky: narrows the segment's [t0, t1] inside it; false if nothing is left.
function clip(p, q, t) {
  if (p === 0) return q > 0; // parallel to this side: inside it or not at all
  const r = q / p;
  if (p < 0) {
    if (r > t[0]) t[0] = r;
  } else if (r < t[1]) t[1] = r;
  return t[0] < t[1];
}

function segmentHitsCircle(s, c) {
  const [x0, y0, x1, y1] = s;
  const dx = x1 - x0;
  const dy = y1 - y0;
  const len2 = dx * dx + dy * dy;
  const t = len2 ? Math.max(0, Math.min(1, ((c.x - x0) * dx + (c.y - y0) * dy) / len2)) : 0;
  const ex = x0 + t * dx - c.x;
  const ey = y0 + t * dy - c.y;
  return ex * ex + ey * ey < c.r * c.r;
}
