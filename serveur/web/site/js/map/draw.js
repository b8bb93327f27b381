// Drawing the map's layers. Every function takes the view (for world <-> screen) and a 2D
// context already set to CSS pixels; positions are in metres in the map frame, y up.

import { statusColour } from "../status.js";

export const WAYPOINT_COLOURS = { table: "#8b5a2b", home: "#2f6fdb", pass: "#138a5b", other: "#666" };
const ROBOT_RADIUS_M = 0.25;
const BLOCKED_COLOUR = "#dc2626";
// A zone's tint by its state: nobody in it, robots in it (room left or not), robots waiting.
export const ZONE_COLOURS = { free: "#0e7490", used: "#b45309", waiting: "#be123c" };
const DRAFT_COLOUR = "#0f766e";

/** A zone's state from its lease row: "waiting" (robots wait for it), "used" (held) or "free". */
export function zoneState(lease) {
  if (lease && lease.waiting && lease.waiting.length) return "waiting";
  if (lease && lease.holders && lease.holders.length) return "used";
  return "free";
}

/**
 * The zones, under everything but the grid: each a translucent polygon tinted by its state
 * (`leases`: zone name -> lease row), its outline solid (dashed when free), its name to the
 * scene's labels at its middle. Returns {zone: state} of what was drawn.
 */
export function drawZones(ctx, view, zones, leases, scene) {
  const drawn = {};
  ctx.save();
  for (const z of zones) {
    if (!z.points || z.points.length < 3) continue;
    const state = zoneState(leases.get(z.name));
    const colour = ZONE_COLOURS[state];
    const pts = z.points.map(([x, y]) => view.toScreen(x, y));
    ctx.beginPath();
    pts.forEach(([x, y], i) => (i ? ctx.lineTo(x, y) : ctx.moveTo(x, y)));
    ctx.closePath();
    ctx.globalAlpha = state === "free" ? 0.12 : 0.22;
    ctx.fillStyle = colour;
    ctx.fill();
    ctx.globalAlpha = 0.9;
    ctx.strokeStyle = colour;
    ctx.lineWidth = 2;
    ctx.setLineDash(state === "free" ? [6, 4] : []);
    ctx.stroke();
    ctx.setLineDash([]);
    ctx.globalAlpha = 1;
    const cx = pts.reduce((a, p) => a + p[0], 0) / pts.length;
    const cy = pts.reduce((a, p) => a + p[1], 0) / pts.length;
    scene.labels.push({ key: `zone:${z.name}`, kind: "zone", of: z.name, text: z.name, x: cx, y: cy, r: 2, colour: darker(colour), size: 12, italic: true, prio: PRIO.zone });
    drawn[z.name] = state;
  }
  ctx.restore();
  return drawn;
}

/** A zone being drawn: its corners joined, and a dashed line on to the cursor (if any). */
export function drawZoneDraft(ctx, view, points, cursor) {
  const pts = points.map(([x, y]) => view.toScreen(x, y));
  ctx.save();
  ctx.strokeStyle = DRAFT_COLOUR;
  ctx.fillStyle = DRAFT_COLOUR;
  ctx.lineWidth = 2.5;
  if (pts.length > 2) {
    ctx.beginPath();
    pts.forEach(([x, y], i) => (i ? ctx.lineTo(x, y) : ctx.moveTo(x, y)));
    ctx.closePath();
    ctx.globalAlpha = 0.15;
    ctx.fill();
    ctx.globalAlpha = 1;
  }
  if (pts.length > 1) {
    ctx.beginPath();
    pts.forEach(([x, y], i) => (i ? ctx.lineTo(x, y) : ctx.moveTo(x, y)));
    ctx.stroke();
  }
  if (cursor && pts.length) {
    const [cx, cy] = view.toScreen(cursor.x, cursor.y);
    const [lx, ly] = pts[pts.length - 1];
    ctx.setLineDash([5, 4]);
    ctx.beginPath();
    ctx.moveTo(lx, ly);
    ctx.lineTo(cx, cy);
    if (pts.length > 1) ctx.lineTo(pts[0][0], pts[0][1]);
    ctx.stroke();
    ctx.setLineDash([]);
  }
  for (const [i, [x, y]] of pts.entries()) {
    ctx.beginPath();
    ctx.arc(x, y, i === 0 ? 7 : 5, 0, 2 * Math.PI);
    ctx.fill();
    ctx.strokeStyle = "#fff";
    ctx.lineWidth = 1.5;
    ctx.stroke();
    ctx.strokeStyle = DRAFT_COLOUR;
    ctx.lineWidth = 2.5;
  }
  if (cursor) {
    const [cx, cy] = view.toScreen(cursor.x, cursor.y);
    ctx.beginPath();
    ctx.moveTo(cx - 10, cy);
    ctx.lineTo(cx + 10, cy);
    ctx.moveTo(cx, cy - 10);
    ctx.lineTo(cx, cy + 10);
    ctx.lineWidth = 2;
    ctx.stroke();
  }
  ctx.restore();
}

/** The occupancy grid, drawn in world units (see grid.js for why no row flip is needed). */
export function drawGrid(ctx, view, map, image) {
  const { resolution, origin, width, height } = map;
  ctx.save();
  // metres -> CSS pixels with y up: the negative y scale turns the bottom-up rows right way up.
  ctx.transform(view.scale, 0, 0, -view.scale, view.ox, view.oy);
  ctx.translate(origin[0], origin[1]);
  ctx.rotate(origin[2] || 0);
  ctx.imageSmoothingEnabled = false;
  ctx.drawImage(image, 0, 0, width * resolution, height * resolution);
  ctx.restore();
}

/** The floor plan under the map (`map.backdrop`, fitted by the owner): its pixel (column, row)
 *  is at scale * R(rotation) * (column, -row) + (tx, ty) on the map; drawn faint, over the grid. */
export function drawBackdrop(ctx, view, backdrop, image) {
  const { scale, rotation, tx, ty } = backdrop;
  const c = Math.cos(rotation);
  const s = Math.sin(rotation);
  ctx.save();
  ctx.globalAlpha = 0.4;
  ctx.transform(view.scale, 0, 0, -view.scale, view.ox, view.oy);
  ctx.transform(scale * c, scale * s, -scale * s, scale * c, tx, ty);
  ctx.scale(1, -1);
  ctx.drawImage(image, 0, 0);
  ctx.restore();
}

/**
 * What the labels are placed around (labels.js), most important first: table names, then the
 * selected robot, the other robots (each with where it is going), homes, the pass and other
 * places, and last the zones' names.
 */
export const PRIO = { table: 0, selected: 1, robot: 2, place: 3, zone: 4 };

/**
 * A frame's labels and what they must not cover, filled by the draw functions below and
 * placed by labels.js once everything is drawn (drawLabels draws them).
 */
export function newScene() {
  return { labels: [], circles: [] };
}

/** Waypoint markers; their names go to the scene's labels (tables' first), the marks under them. */
export function drawWaypoints(ctx, view, waypoints, scene) {
  ctx.save();
  for (const w of waypoints) {
    const [x, y] = view.toScreen(w.x, w.y);
    const r = 6;
    ctx.beginPath();
    ctx.moveTo(x, y - r);
    ctx.lineTo(x + r, y);
    ctx.lineTo(x, y + r);
    ctx.lineTo(x - r, y);
    ctx.closePath();
    ctx.fillStyle = WAYPOINT_COLOURS[w.kind] || WAYPOINT_COLOURS.other;
    ctx.fill();
    ctx.strokeStyle = "#fff";
    ctx.lineWidth = 1.5;
    ctx.stroke();
    scene.circles.push({ x, y, r: r + 1 });
    const table = w.kind === "table";
    scene.labels.push({ key: `place:${w.name}`, kind: w.kind, of: w.name, text: w.name, x, y, r: r + 2, colour: "#222", size: 12, bold: table, keep: table, prio: table ? PRIO.table : PRIO.place });
  }
  ctx.restore();
}

/**
 * The labels as labels.js placed them: first each leader line (from the anchor's edge to a label
 * moved away from it), then the labels; a robot's is a tag in its status colour (its name and
 * where it is going, white on the colour, as on the robot's badge in the list), every other one
 * dark text on a white halo.
 */
export function drawLabels(ctx, placed) {
  ctx.save();
  ctx.lineWidth = 1.5;
  for (const l of placed) {
    if (!l.leader) continue;
    const [x0, y0, x1, y1] = l.leader;
    ctx.strokeStyle = l.colour;
    ctx.beginPath();
    ctx.moveTo(x0, y0);
    ctx.lineTo(x1, y1);
    ctx.stroke();
    ctx.beginPath();
    ctx.arc(x0, y0, 2, 0, 2 * Math.PI);
    ctx.fillStyle = l.colour;
    ctx.fill();
  }
  ctx.textBaseline = "middle";
  ctx.textAlign = "left";
  for (const l of placed) {
    ctx.font = l.font;
    const ty = (l.y0 + l.y1) / 2 + 0.5;
    if (l.kind === "robot") {
      ctx.beginPath();
      if (ctx.roundRect) ctx.roundRect(l.x0, l.y0, l.x1 - l.x0, l.y1 - l.y0, 4);
      else ctx.rect(l.x0, l.y0, l.x1 - l.x0, l.y1 - l.y0);
      ctx.fillStyle = l.colour;
      ctx.fill();
      ctx.strokeStyle = "#fff";
      ctx.lineWidth = 1;
      ctx.stroke();
      ctx.fillStyle = "#fff";
      ctx.fillText(l.text, l.x0 + l.pad, ty);
    } else {
      ctx.lineWidth = 3;
      ctx.strokeStyle = "rgba(255,255,255,0.85)";
      ctx.strokeText(l.text, l.x0 + l.pad, ty);
      ctx.fillStyle = l.colour;
      ctx.fillText(l.text, l.x0 + l.pad, ty);
    }
  }
  ctx.restore();
}

/** A status colour made dark enough to read as text on the light map. */
function darker(hex) {
  const m = /^#([0-9a-f]{6})$/i.exec(hex);
  if (!m) return "#222";
  const n = parseInt(m[1], 16);
  const c = [(n >> 16) & 255, (n >> 8) & 255, n & 255].map((v) => Math.round(v * 0.6));
  return `rgb(${c.join(",")})`;
}

/**
 * The laser scan around a robot. Beam i points at yaw + angle_min + i * angle_increment in the
 * map frame (docs/protocol.md): the scan's own pose is used, so the points stay on the walls
 * however the robot turns — the report's UI forgot the yaw and drew them rotated.
 */
/**
 * Where the robot may be: its localisation's particles (the cloud:<robot> stream), each a short
 * tick in its heading. A tight knot is a robot sure of its place; a spray over the room, a lost
 * one. Drawn under the laser and the robots.
 */
export const CLOUD_COLOUR = "#b45309";
export function drawCloud(ctx, view, cloud) {
  const len = 0.15; // m: a tick a little shorter than a robot's radius
  ctx.save();
  ctx.strokeStyle = CLOUD_COLOUR;
  ctx.globalAlpha = 0.55;
  ctx.lineWidth = 1.5;
  ctx.beginPath();
  for (const [x, y, yaw] of cloud.particles) {
    const [sx, sy] = view.toScreen(x, y);
    const [tx, ty] = view.toScreen(x + len * Math.cos(yaw), y + len * Math.sin(yaw));
    ctx.moveTo(sx, sy);
    ctx.lineTo(tx, ty);
  }
  ctx.stroke();
  ctx.restore();
}

export function drawScan(ctx, view, scan) {
  const { x, y, yaw, angle_min: a0, angle_increment: da, range_max: rmax, ranges } = scan;
  const hits = [];
  const outline = [];
  for (let i = 0; i < ranges.length; i++) {
    const r = ranges[i];
    const hit = r !== null && Number.isFinite(r);
    const a = yaw + a0 + i * da;
    const d = hit ? r : rmax; // no hit: the beam saw free space up to range_max
    const p = view.toScreen(x + d * Math.cos(a), y + d * Math.sin(a));
    outline.push(p);
    if (hit) hits.push(p);
  }
  ctx.save();
  // What the laser sees, lightly; then each return as a dot.
  if (outline.length > 2) {
    ctx.beginPath();
    outline.forEach(([sx, sy], i) => (i ? ctx.lineTo(sx, sy) : ctx.moveTo(sx, sy)));
    ctx.closePath();
    ctx.fillStyle = "rgba(225, 29, 72, 0.07)";
    ctx.fill();
  }
  ctx.fillStyle = "#e11d48";
  const size = Math.max(3, Math.min(5, view.scale * 0.06));
  for (const [sx, sy] of hits) ctx.fillRect(sx - size / 2, sy - size / 2, size, size);
  ctx.restore();
}

/**
 * A trip's later tables, faint: a thin dashed line from the current stop (wps[0]) on through
 * each later one, and a small ring on each. The current stop itself is drawGoal's.
 */
export function drawLaterStops(ctx, view, wps, colour) {
  if (wps.length < 2) return;
  const pts = wps.map((w) => view.toScreen(w.x, w.y));
  ctx.save();
  ctx.globalAlpha = 0.45;
  ctx.strokeStyle = colour;
  ctx.lineWidth = 1.5;
  ctx.setLineDash([3, 4]);
  ctx.beginPath();
  pts.forEach(([x, y], i) => (i ? ctx.lineTo(x, y) : ctx.moveTo(x, y)));
  ctx.stroke();
  ctx.setLineDash([]);
  for (const [x, y] of pts.slice(1)) {
    ctx.beginPath();
    ctx.arc(x, y, 7, 0, 2 * Math.PI);
    ctx.stroke();
  }
  ctx.restore();
}

/** A table robots cannot reach (a block): a red ring crossed over its marker. */
export function drawBlocked(ctx, view, wp) {
  const [x, y] = view.toScreen(wp.x, wp.y);
  const r = 9;
  ctx.save();
  ctx.strokeStyle = BLOCKED_COLOUR;
  ctx.lineWidth = 2.5;
  ctx.beginPath();
  ctx.arc(x, y, r, 0, 2 * Math.PI);
  ctx.moveTo(x - r * 0.7, y - r * 0.7);
  ctx.lineTo(x + r * 0.7, y + r * 0.7);
  ctx.moveTo(x + r * 0.7, y - r * 0.7);
  ctx.lineTo(x - r * 0.7, y + r * 0.7);
  ctx.stroke();
  ctx.restore();
}

/**
 * A dashed line from the robot to where it is going, and that place ringed (tinted inside). Its
 * name is not written there (the table's own name is): the robot's label says where it goes.
 */
export function drawGoal(ctx, view, from, goal, colour, scene) {
  const [x0, y0] = view.toScreen(from.x, from.y);
  const [x1, y1] = view.toScreen(goal.x, goal.y);
  ctx.save();
  ctx.strokeStyle = colour;
  ctx.lineWidth = 2;
  ctx.setLineDash([6, 5]);
  ctx.beginPath();
  ctx.moveTo(x0, y0);
  ctx.lineTo(x1, y1);
  ctx.stroke();
  ctx.setLineDash([]);
  ctx.beginPath();
  ctx.arc(x1, y1, 10, 0, 2 * Math.PI);
  ctx.globalAlpha = 0.18;
  ctx.fillStyle = colour;
  ctx.fill();
  ctx.globalAlpha = 1;
  ctx.lineWidth = 3;
  ctx.stroke();
  if (goal.yaw !== undefined && goal.yaw !== null) arrow(ctx, x1, y1, goal.yaw, 18, colour);
  scene.circles.push({ x: x1, y: y1, r: 12 });
  ctx.restore();
}

/** An arrow from (x, y) in screen pixels, pointing at map-frame angle `yaw`. */
export function arrow(ctx, x, y, yaw, length, colour) {
  const dx = Math.cos(yaw) * length;
  const dy = -Math.sin(yaw) * length; // screen y grows downward
  ctx.save();
  ctx.strokeStyle = colour;
  ctx.fillStyle = colour;
  ctx.lineWidth = 3;
  ctx.beginPath();
  ctx.moveTo(x, y);
  ctx.lineTo(x + dx, y + dy);
  ctx.stroke();
  const a = Math.atan2(dy, dx);
  ctx.beginPath();
  ctx.moveTo(x + dx, y + dy);
  ctx.lineTo(x + dx - 10 * Math.cos(a - 0.45), y + dy - 10 * Math.sin(a - 0.45));
  ctx.lineTo(x + dx - 10 * Math.cos(a + 0.45), y + dy - 10 * Math.sin(a + 0.45));
  ctx.closePath();
  ctx.fill();
  ctx.restore();
}

/**
 * A robot: a disc in its status colour, its heading a white wedge, ringed when selected; its
 * label (`text`: its name, and where it is going) to the scene, placed beside it (labels.js).
 */
export function drawRobot(ctx, view, name, pose, status, selected, scene, text = name) {
  const [x, y] = view.toScreen(pose.x, pose.y);
  const r = Math.max(8, ROBOT_RADIUS_M * view.scale);
  const colour = statusColour(status);
  ctx.save();
  if (selected) {
    ctx.beginPath();
    ctx.arc(x, y, r + 5, 0, 2 * Math.PI);
    ctx.strokeStyle = "#ffb000";
    ctx.lineWidth = 3;
    ctx.stroke();
  }
  ctx.beginPath();
  ctx.arc(x, y, r, 0, 2 * Math.PI);
  ctx.fillStyle = colour;
  ctx.fill();
  ctx.strokeStyle = "#fff";
  ctx.lineWidth = 2;
  ctx.stroke();
  // Heading: a white wedge from the centre to the rim.
  const dx = Math.cos(pose.yaw);
  const dy = -Math.sin(pose.yaw);
  ctx.beginPath();
  ctx.moveTo(x + dx * r, y + dy * r);
  ctx.lineTo(x - dy * r * 0.45, y + dx * r * 0.45);
  ctx.lineTo(x + dy * r * 0.45, y - dx * r * 0.45);
  ctx.closePath();
  ctx.fillStyle = "#fff";
  ctx.fill();
  // No status word: robots park side by side, and the status is the colour (and in the list).
  const rim = r + (selected ? 6.5 : 1);
  scene.circles.push({ x, y, r: rim });
  scene.labels.push({ key: `robot:${name}`, kind: "robot", of: name, text, short: name, x, y, r: rim, colour, size: 12, bold: true, pad: 4, keep: true, prio: selected ? PRIO.selected : PRIO.robot });
  ctx.restore();
}
