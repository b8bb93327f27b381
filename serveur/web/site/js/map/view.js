// The map canvas: world <-> screen transform, zoom and pan (mouse, wheel, touch pinch), and the
// RViz-style pose tools (press where, drag toward the heading) for calibration and goals.
//
// The transform: screen = (ox + x * scale, oy - y * scale) in CSS pixels relative to the canvas,
// with `scale` in pixels per metre. The map's resolution and origin only matter for drawing the
// grid (draw.js); every other position on the map is already in metres in the map frame.
// The view is published on the canvas as data-scale / data-origin-x / data-origin-y so tests
// and tools can aim at a map position; data-draws counts the frames drawn.
//
// Drawing happens only when something changed (requestDraw, at most once per animation frame),
// and not while the map is hidden (another tab): a parked fleet costs nothing.
//
// The keyboard: the canvas takes focus; arrow keys pan, + and - zoom. With a pose tool on
// (Calibrate, Move here), a cursor starts on the selected robot: arrow keys move it (Shift: in
// bigger steps), [ and ] turn its heading, Enter confirms, Escape cancels.
//
// Follow (setFollow): each frame drawn puts the selected robot in the middle, the zoom kept.
// A frame is drawn when the robot's pose changes, as for everything else: no frame loop. Any
// pan or zoom by hand turns following off (the canvas fires "followchange"), as does Escape
// (maptools.js). data-follow says whether it is on.
//
// Each robot on a trip: a dashed line to the table it is going to (or waiting at), that table
// ringed, and faint lines on to its later tables; data-routes publishes what was drawn
// ({robot: [current table, later tables...]}). Tables robots cannot reach (blocks) are crossed
// (data-blocked lists them).
//
// Zones (live.zones, tinted by live.leases) are drawn under everything but the grid; data-zones
// publishes {zone: "free" | "used" | "waiting"} as drawn. The "zone" tool draws one: a click or
// tap (not a drag: dragging still pans) adds a corner, a click on the first corner closes it;
// from the keyboard, arrow keys move a cross, Enter adds a corner there, Enter again on the last
// corner closes it (3 corners at least), Backspace takes the last corner back, Escape cancels.
// The corners so far are published as data-draft; finishZone() closes the zone (Finish button).
//
// Labels (labels.js places them, draw.js draws them): none covers another, a place's marker, a
// robot or a control or message laid over the map (the legend, an armed tool's instruction: see
// _covers), at any zoom and size; table names come first, then robots, then homes,
// the pass and zones; a label that cannot go next to its mark goes a little further, on a leader
// line, then smaller, and the least important is left out. A robot's label is its name and
// where it is going ("r1 → T5"), a tag in its status colour beside the robot (on a line to it
// when moved away): nothing is written at the destination but the table's own name, so no
// destination can be read as the name of the table it lies next to, and a waiter reads who goes
// where at a glance, on a phone too (no hover there). Placed once per frame drawn, so only when
// something moved. labels() returns what was placed; data-labels publishes the boxes, and
// data-label-info each label's text, kind, subject, box, anchor and leader (and those left out).

import { decodeGrid } from "./grid.js";
import { placeLabels } from "./labels.js";
import {
  arrow,
  drawBlocked,
  drawGoal,
  drawBackdrop,
  drawGrid,
  drawLabels,
  drawLaterStops,
  drawRobot,
  drawScan,
  drawCloud,
  drawWaypoints,
  drawZoneDraft,
  drawZones,
  newScene,
} from "./draw.js";
import { statusColour } from "../status.js";
import { t } from "../i18n.js";

const MIN_SCALE = 5;
const MAX_SCALE = 400;
const CLICK_SLOP_PX = 6;
const TOOL_COLOURS = { initialpose: "#15803d", goal: "#7c3aed" };
export const CONSOLE_GOAL_COLOUR = TOOL_COLOURS.goal; // a goal sent from this console (Move here)
const KEY_STEP_M = 0.1; // a cursor step; Shift: five
const KEY_TURN = Math.PI / 12; // 15 degrees
const KEY_PAN_PX = 40;
const CLOSE_PX = 14; // a click this near the first corner closes the zone
const MEASURED_MAX = 2000; // text widths kept (font + text -> px): a frame measures none again

export class MapView {
  /**
   * @param canvas the <canvas>
   * @param live the Live state (map, waypoints, robots, poses, scans)
   * @param opts.selected () => the selected robot's name or null
   * @param opts.goals () => Map robot -> {x, y, yaw, label} of goals this console sent
   * @param opts.onPose (tool, {x, y, yaw}) after a press-and-drag with a pose tool
   * @param opts.onSelect (robotName) after a click on a robot
   * @param opts.onCancel () after Escape cancels a pose tool
   * @param opts.onCursor ({x, y, yaw} or null) when the keyboard's mark moves or goes
   * @param opts.onZone ([[x, y], ...]) when the zone tool's polygon is closed (3 corners or more)
   * @param opts.onDraft ([[x, y], ...]) when a corner is added or taken back
   */
  constructor(canvas, live, opts) {
    this.canvas = canvas;
    this.live = live;
    this.opts = opts;
    this.ctx = canvas.getContext("2d");
    this.scale = 40;
    this.ox = 0;
    this.oy = 0;
    this.userMoved = false; // until the person zooms or pans, keep the whole map in view
    this.tool = "pan";
    this._image = null;
    this._imageOf = null;
    this._pointers = new Map();
    this._gesture = null;
    this._frame = 0;
    this._dirty = true;
    this._draws = 0;
    this._cursor = null; // the keyboard's pose cursor: {x, y, yaw}
    this.draft = null; // the zone tool's corners so far: [[x, y], ...]
    this.following = false; // keep the selected robot in the middle (setFollow)
    this._placed = { placed: [], dropped: [], hidden: [] }; // the last frame's labels
    this._labelPos = new Map(); // label key -> its position in the last frame (labels stay put)
    this._widths = new Map();
    canvas.dataset.follow = "off";
    this._listen();
    new ResizeObserver(() => this._resize()).observe(canvas);
    // Controls over the map (the legend opening, a tool's instruction) hide labels: place them
    // again when they change.
    const covers = new ResizeObserver(() => this.requestDraw());
    for (const el of this._coverCandidates()) covers.observe(el);
    this._resize();
  }

  /** The labels of the last frame drawn: {placed, dropped, hidden} (labels.js placeLabels). */
  labels() {
    return this._placed;
  }

  _coverCandidates() {
    const parent = this.canvas.parentElement;
    return parent ? [...parent.children].filter((el) => el !== this.canvas) : [];
  }

  /** The boxes, in canvas pixels, of the controls and messages laid over the map: a shown
   *  sibling of the canvas over it that takes pointers (the legend) or has words (an armed tool's
   *  instruction); not a mark without words that lets pointers through (the setup page's pin). */
  _covers() {
    const c = this.canvas.getBoundingClientRect();
    const left = c.left + this.canvas.clientLeft; // drawing starts inside the canvas's border
    const top = c.top + this.canvas.clientTop;
    const boxes = [];
    for (const el of this._coverCandidates()) {
      if (el.offsetParent === null) continue;
      const r = el.getBoundingClientRect();
      if (!r.width || !r.height || r.right <= c.left || r.left >= c.right || r.bottom <= c.top || r.top >= c.bottom) continue;
      if (getComputedStyle(el).pointerEvents === "none" && !el.textContent.trim()) continue;
      boxes.push({ x0: r.left - left, y0: r.top - top, x1: r.right - left, y1: r.bottom - top });
    }
    return boxes;
  }

  _measure(font, text) {
    const key = `${font}\n${text}`;
    let w = this._widths.get(key);
    if (w === undefined) {
      if (this._widths.size >= MEASURED_MAX) this._widths.clear();
      this.ctx.font = font;
      w = this.ctx.measureText(text).width;
      this._widths.set(key, w);
    }
    return w;
  }

  toScreen(x, y) {
    return [this.ox + x * this.scale, this.oy - y * this.scale];
  }

  toWorld(sx, sy) {
    return [(sx - this.ox) / this.scale, (this.oy - sy) / this.scale];
  }

  setTool(tool) {
    this.tool = tool;
    this.canvas.dataset.tool = tool;
    this._gesture = null;
    this._cursor = null;
    this.draft = tool === "zone" ? [] : null;
    this._publishDraft();
    this._publishCursor();
    this.requestDraw();
  }

  _publishDraft() {
    if (this.draft) {
      this.canvas.dataset.draft = JSON.stringify(this.draft.map(([x, y]) => [round2(x), round2(y)]));
    } else {
      delete this.canvas.dataset.draft;
    }
    if (this.opts.onDraft && this.draft) this.opts.onDraft(this.draft);
  }

  /** The zone tool: add a corner at map point (x, y). */
  addCorner(x, y) {
    if (!this.draft) return;
    this.draft.push([x, y]);
    this._publishDraft();
    this.requestDraw();
  }

  /** The zone tool: close the polygon drawn so far (3 corners at least); false if too few. */
  finishZone() {
    if (!this.draft || this.draft.length < 3) return false;
    const points = this.draft.map(([x, y]) => [round2(x), round2(y)]);
    this.opts.onZone(points);
    return true;
  }

  /** Start the keyboard cursor of the current pose tool on the selected robot and focus the map. */
  startKeyboardTool() {
    if (this.tool === "pan") return;
    if (this.tool === "zone") {
      // A cross on the last corner, else in the middle of the view.
      const last = this.draft && this.draft[this.draft.length - 1];
      const [cx, cy] = last || this.toWorld(this.canvas.clientWidth / 2, this.canvas.clientHeight / 2);
      this._cursor = { x: round2(cx), y: round2(cy), yaw: 0 };
      this._publishCursor();
      this.canvas.focus();
      this.requestDraw();
      return;
    }
    const name = this.opts.selected();
    const p = (name && this.live.pose(name)) || { x: 0, y: 0, yaw: 0 };
    const [cx, cy] = this.toWorld(this.canvas.clientWidth / 2, this.canvas.clientHeight / 2);
    this._cursor = name && this.live.pose(name) ? { x: p.x, y: p.y, yaw: p.yaw } : { x: cx, y: cy, yaw: 0 };
    this._publishCursor();
    this.canvas.focus();
    this.requestDraw();
  }

  _publishCursor() {
    const c = this._cursor;
    if (c) {
      this.canvas.dataset.cursor = `${c.x.toFixed(2)},${c.y.toFixed(2)},${c.yaw.toFixed(3)}`;
    } else {
      delete this.canvas.dataset.cursor;
    }
    if (this.opts.onCursor) this.opts.onCursor(c); // said aloud: the hint is a live region
  }

  /** Keep the selected robot in the middle of the view (each frame drawn), or stop. */
  setFollow(on) {
    on = Boolean(on);
    if (on === this.following) return;
    this.following = on;
    this.canvas.dataset.follow = on ? "on" : "off";
    if (on) {
      this.userMoved = true; // a resize or a new map must not fit the whole map over it
      this.requestDraw();
    }
    this.canvas.dispatchEvent(new CustomEvent("followchange", { detail: { on } }));
  }

  /** Following: the view's origin such that the selected robot is in the middle. */
  _centreOnFollowed() {
    const name = this.opts.selected();
    const p = name && this.live.pose(name);
    const w = this.canvas.clientWidth;
    const h = this.canvas.clientHeight;
    if (!p || !w || !h) return;
    this.ox = w / 2 - p.x * this.scale;
    this.oy = h / 2 + p.y * this.scale;
    this._publishView();
  }

  zoomBy(factor, sx = this.canvas.clientWidth / 2, sy = this.canvas.clientHeight / 2) {
    this.setFollow(false); // zoomed by hand: the person looks somewhere else
    const next = Math.min(MAX_SCALE, Math.max(MIN_SCALE, this.scale * factor));
    const [wx, wy] = this.toWorld(sx, sy);
    this.scale = next;
    // keep the world point under the cursor (or centre) where it was
    this.ox = sx - wx * next;
    this.oy = sy + wy * next;
    this.userMoved = true;
    this._viewChanged();
  }

  panBy(dx, dy) {
    this.setFollow(false);
    this.ox += dx;
    this.oy += dy;
    this.userMoved = true;
    this._viewChanged();
  }

  /** Whole map in view, centred. */
  fit() {
    const map = this.live.map;
    const w = this.canvas.clientWidth;
    const h = this.canvas.clientHeight;
    if (!map || !w || !h) return;
    this.setFollow(false);
    const mw = map.width * map.resolution;
    const mh = map.height * map.resolution;
    const margin = 16;
    this.scale = Math.max(MIN_SCALE, Math.min((w - 2 * margin) / mw, (h - 2 * margin) / mh));
    const cx = map.origin[0] + mw / 2;
    const cy = map.origin[1] + mh / 2;
    this.ox = w / 2 - cx * this.scale;
    this.oy = h / 2 + cy * this.scale;
    this.userMoved = false;
    this._viewChanged();
  }

  /** Something shown changed: draw once, at the next animation frame, if the map is visible. */
  requestDraw() {
    this._dirty = true;
    if (this._frame || !this.canvas.isConnected || this.canvas.offsetParent === null) return;
    this._frame = requestAnimationFrame(() => {
      this._frame = 0;
      if (this._dirty) this._drawNow();
    });
  }

  _viewChanged() {
    this._publishView();
    this.requestDraw();
  }

  _publishView() {
    const d = this.canvas.dataset;
    d.scale = String(this.scale);
    d.originX = String(this.ox);
    d.originY = String(this.oy);
  }

  _resize() {
    const dpr = window.devicePixelRatio || 1;
    const w = this.canvas.clientWidth;
    const h = this.canvas.clientHeight;
    this.canvas.width = Math.max(1, Math.round(w * dpr));
    this.canvas.height = Math.max(1, Math.round(h * dpr));
    if (!this.userMoved) this.fit();
    this._viewChanged();
    // A new size cleared the canvas: draw now (before the paint), not a blank frame first.
    if (w && h) this._drawNow();
  }

  /** The floor plan's image at `url` once loaded (null until then: it draws when it comes). */
  _backdrop(url) {
    if (!this._plan || this._plan.url !== url) {
      const image = new Image();
      this._plan = { url, image, ready: false };
      image.onload = () => {
        if (this._plan && this._plan.image === image) {
          this._plan.ready = true;
          this.requestDraw();
        }
      };
      image.src = url;
    }
    return this._plan.ready ? this._plan.image : null;
  }

  _drawNow() {
    if (this._frame) cancelAnimationFrame(this._frame);
    this._frame = 0;
    this._dirty = false;
    if (this.following) this._centreOnFollowed();
    this._draw();
    this.canvas.dataset.draws = String(++this._draws);
  }

  _draw() {
    const { ctx, canvas, live } = this;
    const dpr = window.devicePixelRatio || 1;
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0); // CSS pixels from here on
    ctx.fillStyle = "#e9ecef";
    ctx.fillRect(0, 0, canvas.clientWidth, canvas.clientHeight);
    const map = live.map;
    if (map) {
      if (this._imageOf !== map) {
        this._image = decodeGrid(map);
        this._imageOf = map;
        if (!this.userMoved) this.fit();
      }
      drawGrid(ctx, this, map, this._image);
      const plan = map.backdrop && this._backdrop(map.backdrop.url);
      if (plan) drawBackdrop(ctx, this, map.backdrop, plan);
      this.canvas.dataset.backdrop = String(Boolean(plan));
    } else {
      ctx.fillStyle = "#555";
      ctx.font = "16px system-ui, sans-serif";
      ctx.fillText(t("map.none"), 20, 30);
    }
    // Labels are placed last, once everything they must not cover is drawn (labels.js).
    const scene = newScene();
    const zones = [...live.zones.values()].sort((a, b) => (a.name < b.name ? -1 : 1));
    this.canvas.dataset.zones = JSON.stringify(drawZones(ctx, this, zones, live.leases, scene));
    drawWaypoints(ctx, this, [...live.waypoints.values()], scene);
    const selected = this.opts.selected();
    const cloud = selected && live.clouds.get(selected);
    if (cloud) drawCloud(ctx, this, cloud);
    this.canvas.dataset.cloud = String(cloud ? cloud.particles.length : 0); // particles drawn
    const scan = selected && live.scans.get(selected);
    if (scan) drawScan(ctx, this, scan);
    const blocked = [...live.blocks.keys()].filter((table) => live.waypoints.has(table));
    for (const table of blocked) drawBlocked(ctx, this, live.waypoints.get(table));
    this.canvas.dataset.blocked = JSON.stringify(blocked.sort());
    const goals = this.opts.goals();
    const routes = {};
    const going = new Map(); // robot -> where it is going, as its label says it
    for (const [name, robot] of live.robots) {
      const pose = live.pose(name);
      if (!pose) continue;
      const colour = statusColour(robot.status);
      const stops = this.route(name).filter((s) => live.waypoints.has(s));
      if (stops.length) {
        const wps = stops.map((s) => live.waypoints.get(s));
        drawLaterStops(ctx, this, wps, colour);
        drawGoal(ctx, this, pose, wps[0], colour, scene);
        routes[name] = stops;
        going.set(name, stops[0]);
      } else if (goals.has(name)) {
        drawGoal(ctx, this, pose, goals.get(name), CONSOLE_GOAL_COLOUR, scene);
        routes[name] = ["goal"];
        going.set(name, t("map.goalLabel"));
      }
    }
    this.canvas.dataset.routes = JSON.stringify(routes);
    for (const [name, robot] of live.robots) {
      const pose = live.pose(name);
      const text = going.has(name) ? `${name} → ${going.get(name)}` : name;
      if (pose) drawRobot(ctx, this, name, pose, robot.status, name === selected, scene, text);
    }
    const g = this._gesture;
    const c = this._cursor;
    if (this.tool === "zone" && this.draft) drawZoneDraft(ctx, this, this.draft, c);
    const pick = g && g.kind === "pose" ? g : c;
    if (pick && TOOL_COLOURS[this.tool]) {
      const [sx, sy] = this.toScreen(pick.x, pick.y);
      ctx.beginPath();
      ctx.arc(sx, sy, c === pick ? 10 : 6, 0, 2 * Math.PI);
      ctx.fillStyle = TOOL_COLOURS[this.tool];
      ctx.fill();
      if (pick.yaw !== null) arrow(ctx, sx, sy, pick.yaw, 40, TOOL_COLOURS[this.tool]);
    }
    this._placeLabels(scene);
  }

  /** Place the frame's labels (labels.js), draw them and publish them. */
  _placeLabels(scene) {
    const { ctx, canvas } = this;
    const found = placeLabels(
      scene.labels,
      { circles: scene.circles, rects: this._covers(), width: canvas.clientWidth, height: canvas.clientHeight },
      (font, text) => this._measure(font, text),
      this._labelPos,
    );
    this._placed = found;
    this._labelPos = new Map(found.placed.map((l) => [l.key, l.pos]));
    drawLabels(ctx, found.placed);
    const px = (v) => Math.round(v * 10) / 10; // rounding keeps the boxes' order: apart stays apart
    canvas.dataset.labels = JSON.stringify(found.placed.map((l) => [l.x0, l.y0, l.x1, l.y1].map(px)));
    canvas.dataset.labelInfo = JSON.stringify({
      placed: found.placed.map((l) => ({
        text: l.text,
        kind: l.kind,
        of: l.of,
        box: [l.x0, l.y0, l.x1, l.y1].map(px),
        anchor: [px(l.ax), px(l.ay), px(l.ar)],
        leader: l.leader ? l.leader.map(px) : null,
      })),
      dropped: found.dropped,
      hidden: found.hidden,
    });
  }

  /**
   * The tables robot `name` still has to visit on its trip: the one it is going to or waiting
   * at (live.destination), then the later stops not served yet, in visiting order.
   */
  route(name) {
    const { live } = this;
    const r = live.robots.get(name);
    const task = r && r.current_task !== null && r.current_task !== undefined ? live.tasks.get(r.current_task) : null;
    const now = task && task.stops[task.current_stop];
    if (!now) return [];
    const later = task.stops.slice(task.current_stop + 1).filter((s) => s.status === "pending");
    return [now.table, ...later.map((s) => s.table)];
  }

  _local(ev) {
    const rect = this.canvas.getBoundingClientRect();
    return [ev.clientX - rect.left, ev.clientY - rect.top];
  }

  _listen() {
    const c = this.canvas;
    c.tabIndex = 0;
    c.addEventListener("keydown", (ev) => this._key(ev));
    c.addEventListener("pointerdown", (ev) => this._down(ev));
    c.addEventListener("pointermove", (ev) => this._move(ev));
    c.addEventListener("pointerup", (ev) => this._up(ev, false));
    c.addEventListener("pointercancel", (ev) => this._up(ev, true));
    c.addEventListener(
      "wheel",
      (ev) => {
        ev.preventDefault();
        const [sx, sy] = this._local(ev);
        this.zoomBy(Math.exp(-ev.deltaY * 0.0015), sx, sy);
      },
      { passive: false },
    );
  }

  _down(ev) {
    this.canvas.setPointerCapture(ev.pointerId);
    const [sx, sy] = this._local(ev);
    this._pointers.set(ev.pointerId, [sx, sy]);
    if (this._pointers.size === 2) {
      // A second finger turns any gesture into a pinch: zoom and pan together.
      const [a, b] = [...this._pointers.values()];
      this._gesture = { kind: "pinch", dist: Math.hypot(a[0] - b[0], a[1] - b[1]), mid: mid(a, b) };
      return;
    }
    if (this._pointers.size > 2) return;
    if (this.tool === "pan" || this.tool === "zone") {
      this._gesture = { kind: "pan", sx, sy, lastX: sx, lastY: sy, moved: false };
    } else {
      const [x, y] = this.toWorld(sx, sy);
      this._gesture = { kind: "pose", sx, sy, x, y, yaw: null };
    }
    this.requestDraw();
  }

  _move(ev) {
    if (!this._pointers.has(ev.pointerId)) return;
    const [sx, sy] = this._local(ev);
    this._pointers.set(ev.pointerId, [sx, sy]);
    const g = this._gesture;
    if (!g) return;
    if (g.kind === "pinch" && this._pointers.size === 2) {
      const [a, b] = [...this._pointers.values()];
      const dist = Math.hypot(a[0] - b[0], a[1] - b[1]);
      const m = mid(a, b);
      this.panBy(m[0] - g.mid[0], m[1] - g.mid[1]);
      if (g.dist > 0) this.zoomBy(dist / g.dist, m[0], m[1]);
      g.dist = dist;
      g.mid = m;
    } else if (g.kind === "pan") {
      if (Math.hypot(sx - g.sx, sy - g.sy) > CLICK_SLOP_PX) g.moved = true;
      if (g.moved) this.panBy(sx - g.lastX, sy - g.lastY);
      g.lastX = sx;
      g.lastY = sy;
    } else if (g.kind === "pose") {
      if (Math.hypot(sx - g.sx, sy - g.sy) > CLICK_SLOP_PX) {
        g.yaw = Math.atan2(-(sy - g.sy), sx - g.sx); // screen y is down, map y is up
      }
      this.requestDraw();
    }
  }

  _up(ev, cancelled) {
    if (!this._pointers.delete(ev.pointerId)) return;
    const g = this._gesture;
    if (this._pointers.size > 0) {
      // One finger of a pinch lifted: carry on panning with the other, no action.
      if (g && g.kind === "pinch") this._gesture = null;
      return;
    }
    this._gesture = null;
    this.requestDraw();
    if (!g || cancelled) return;
    if (g.kind === "pan" && !g.moved && this.tool === "zone") {
      this._cornerAt(g.sx, g.sy);
    } else if (g.kind === "pan" && !g.moved) {
      const name = this._robotAt(g.sx, g.sy);
      if (name) this.opts.onSelect(name);
    } else if (g.kind === "pose") {
      this.opts.onPose(this.tool, { x: g.x, y: g.y, yaw: g.yaw });
    }
  }

  /** A click or tap with the zone tool: a corner, or the zone closed on its first corner. */
  _cornerAt(sx, sy) {
    const first = this.draft && this.draft[0];
    if (first && this.draft.length >= 3) {
      const [fx, fy] = this.toScreen(first[0], first[1]);
      if (Math.hypot(fx - sx, fy - sy) <= CLOSE_PX) {
        this.finishZone();
        return;
      }
    }
    const [x, y] = this.toWorld(sx, sy);
    this.addCorner(x, y);
  }

  /** The zone tool's keys; true if the key was the tool's. */
  _zoneKey(ev) {
    const arrows = { ArrowLeft: [-1, 0], ArrowRight: [1, 0], ArrowUp: [0, 1], ArrowDown: [0, -1] };
    if (ev.key === "Escape") {
      this._cursor = null;
      this._publishCursor();
      if (this.opts.onCancel) this.opts.onCancel();
      return true;
    }
    if (ev.key === "Backspace" && this.draft && this.draft.length) {
      this.draft.pop();
      this._publishDraft();
      this.requestDraw();
      return true;
    }
    if (!(ev.key in arrows) && ev.key !== "Enter") return false;
    if (!this._cursor) {
      this.startKeyboardTool(); // the first key shows the cross; the next ones move it
      return true;
    }
    const cur = this._cursor;
    if (ev.key === "Enter") {
      const last = this.draft[this.draft.length - 1];
      const onLast = last && Math.hypot(last[0] - cur.x, last[1] - cur.y) < 1e-6;
      if (onLast && this.draft.length >= 3) this.finishZone();
      else if (!onLast) this.addCorner(cur.x, cur.y);
      return true;
    }
    const [dx, dy] = arrows[ev.key];
    const step = KEY_STEP_M * (ev.shiftKey ? 5 : 1);
    cur.x = round2(cur.x + dx * step);
    cur.y = round2(cur.y + dy * step);
    this._publishCursor();
    this.requestDraw();
    return true;
  }

  _key(ev) {
    if (this.tool === "zone") {
      if (this._zoneKey(ev)) {
        ev.preventDefault();
        return;
      }
      if (ev.key === "Backspace") return;
    }
    const arrows = { ArrowLeft: [-1, 0], ArrowRight: [1, 0], ArrowUp: [0, 1], ArrowDown: [0, -1] };
    const c = this._cursor;
    if (this.tool !== "pan" && !c && (ev.key in arrows || ev.key === "Enter")) this.startKeyboardTool();
    const cur = this._cursor;
    if (cur) {
      if (ev.key in arrows) {
        const [dx, dy] = arrows[ev.key];
        const step = KEY_STEP_M * (ev.shiftKey ? 5 : 1);
        cur.x += dx * step;
        cur.y += dy * step;
      } else if (ev.key === "[" || ev.key === "]") {
        const yaw = cur.yaw + (ev.key === "[" ? KEY_TURN : -KEY_TURN);
        cur.yaw = Math.atan2(Math.sin(yaw), Math.cos(yaw));
      } else if (ev.key === "Enter") {
        const pose = { ...cur };
        this._cursor = null;
        this._publishCursor();
        this.opts.onPose(this.tool, pose);
      } else if (ev.key === "Escape") {
        this._cursor = null;
        this._publishCursor();
        if (this.opts.onCancel) this.opts.onCancel();
      } else return;
      ev.preventDefault();
      this._publishCursor();
      this.requestDraw();
      return;
    }
    if (ev.key === "Escape" && this.tool !== "pan" && this.opts.onCancel) {
      ev.preventDefault();
      this.opts.onCancel();
    } else if (ev.key in arrows) {
      ev.preventDefault();
      const [dx, dy] = arrows[ev.key];
      this.panBy(-dx * KEY_PAN_PX, dy * KEY_PAN_PX);
    } else if (ev.key === "+" || ev.key === "=") {
      ev.preventDefault();
      this.zoomBy(1.25);
    } else if (ev.key === "-") {
      ev.preventDefault();
      this.zoomBy(0.8);
    }
  }

  _robotAt(sx, sy) {
    let best = null;
    let bestD = 28;
    for (const name of this.live.robots.keys()) {
      const p = this.live.pose(name);
      if (!p) continue;
      const [x, y] = this.toScreen(p.x, p.y);
      const d = Math.hypot(x - sx, y - sy);
      if (d < bestD) [best, bestD] = [name, d];
    }
    return best;
  }
}

function round2(v) {
  return Math.round(v * 100) / 100;
}

function mid(a, b) {
  return [(a[0] + b[0]) / 2, (a[1] + b[1]) / 2];
}
