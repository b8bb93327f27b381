// The map canvas: world <-> screen transform, zoom and pan (mouse, wheel, touch pinch), and the
// RViz-style pose tools (press where, drag toward the heading) for calibration and goals.
//
// The transform: screen = (ox + x * scale, oy - y * scale) in CSS pixels relative to the canvas,
// with `scale` in pixels per metre. The map's resolution and origin only matter for drawing the
// grid (draw.js); every other position on the map is already in metres in the map frame.
// The view is published on the canvas as data-scale / data-origin-x / data-origin-y so tests
// and tools can aim at a map position.

import { decodeGrid } from "./grid.js";
import { arrow, drawGoal, drawGrid, drawRobot, drawScan, drawWaypoints } from "./draw.js";
import { statusColour } from "../status.js";
import { t } from "../i18n.js";

const MIN_SCALE = 5;
const MAX_SCALE = 400;
const CLICK_SLOP_PX = 6;
const TOOL_COLOURS = { initialpose: "#16a34a", goal: "#7c3aed" };

export class MapView {
  /**
   * @param canvas the <canvas>
   * @param live the Live state (map, waypoints, robots, poses, scans)
   * @param opts.selected () => the selected robot's name or null
   * @param opts.goals () => Map robot -> {x, y, yaw, label} of goals this console sent
   * @param opts.onPose (tool, {x, y, yaw}) after a press-and-drag with a pose tool
   * @param opts.onSelect (robotName) after a click on a robot
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
    this._listen();
    new ResizeObserver(() => this._resize()).observe(canvas);
    this._resize();
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
    this.requestDraw();
  }

  zoomBy(factor, sx = this.canvas.clientWidth / 2, sy = this.canvas.clientHeight / 2) {
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

  requestDraw() {
    if (this._frame) return;
    this._frame = requestAnimationFrame(() => {
      this._frame = 0;
      this._draw();
    });
  }

  _viewChanged() {
    const d = this.canvas.dataset;
    d.scale = String(this.scale);
    d.originX = String(this.ox);
    d.originY = String(this.oy);
    this.requestDraw();
  }

  _resize() {
    const dpr = window.devicePixelRatio || 1;
    const w = this.canvas.clientWidth;
    const h = this.canvas.clientHeight;
    this.canvas.width = Math.max(1, Math.round(w * dpr));
    this.canvas.height = Math.max(1, Math.round(h * dpr));
    if (!this.userMoved) this.fit();
    this._viewChanged();
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
    } else {
      ctx.fillStyle = "#555";
      ctx.font = "16px system-ui, sans-serif";
      ctx.fillText(t("map.none"), 20, 30);
    }
    drawWaypoints(ctx, this, [...live.waypoints.values()]);
    const selected = this.opts.selected();
    const scan = selected && live.scans.get(selected);
    if (scan) drawScan(ctx, this, scan);
    const goals = this.opts.goals();
    for (const [name, robot] of live.robots) {
      const pose = live.pose(name);
      if (!pose) continue;
      const colour = statusColour(robot.status);
      const table = live.destination(name);
      const wp = table && live.waypoints.get(table);
      if (wp) drawGoal(ctx, this, pose, { ...wp, label: table }, colour);
      else if (goals.has(name)) drawGoal(ctx, this, pose, { label: t("map.goalLabel"), ...goals.get(name) }, colour);
    }
    for (const [name, robot] of live.robots) {
      const pose = live.pose(name);
      if (pose) drawRobot(ctx, this, name, pose, robot.status, name === selected);
    }
    const g = this._gesture;
    if (g && g.kind === "pose") {
      const [sx, sy] = this.toScreen(g.x, g.y);
      ctx.beginPath();
      ctx.arc(sx, sy, 6, 0, 2 * Math.PI);
      ctx.fillStyle = TOOL_COLOURS[this.tool];
      ctx.fill();
      if (g.yaw !== null) arrow(ctx, sx, sy, g.yaw, 40, TOOL_COLOURS[this.tool]);
    }
  }

  _local(ev) {
    const rect = this.canvas.getBoundingClientRect();
    return [ev.clientX - rect.left, ev.clientY - rect.top];
  }

  _listen() {
    const c = this.canvas;
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
    if (this.tool === "pan") {
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
    if (g.kind === "pan" && !g.moved) {
      const name = this._robotAt(g.sx, g.sy);
      if (name) this.opts.onSelect(name);
    } else if (g.kind === "pose") {
      this.opts.onPose(this.tool, { x: g.x, y: g.y, yaw: g.yaw });
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

function mid(a, b) {
  return [(a[0] + b[0]) / 2, (a[1] + b[1]) / 2];
}
