// The map toolbar: Calibrate (initialpose) and Move here (goal) as one-shot press-and-drag
// tools like RViz's 2D Pose Estimate / 2D Nav Goal, and zoom buttons. From the keyboard, a tool
// button pressed with Enter or Space puts a cursor on the map (view.js: arrow keys move it, [ and
// ] turn it, Enter confirms, Escape cancels); focus then returns to the tool's button.
// Follow robot (aria-pressed) keeps the selected robot in the middle of the map (view.js
// setFollow); a pan or zoom by hand, or Escape anywhere, turns it off.
// The map's legend (staff.html #map-legend) takes its swatches' colours from the drawing code
// and is kept no taller than the map.

import { act, toast } from "../ui.js";
import { allowed, statusColour } from "../status.js";
import { WAYPOINT_COLOURS } from "../map/draw.js";
import { onLangChange, t } from "../i18n.js";

// hint: a catalog key.
const TOOLS = {
  initialpose: { button: "tool-calibrate", hint: "map.calibrateHintFull" },
  goal: { button: "tool-goal", hint: "map.goalHintFull" },
};
const REACHED_M = 0.3;

export class MapTools {
  constructor(conn, live, view, selection, goals) {
    this.conn = conn;
    this.live = live;
    this.view = view;
    this.selection = selection;
    this.goals = goals;
    this.hint = document.getElementById("tool-hint");
    for (const [tool, { button }] of Object.entries(TOOLS)) {
      document.getElementById(button).addEventListener("click", (e) => {
        this._setTool(this.view.tool === tool ? "pan" : tool);
        // detail 0: pressed from the keyboard, so the keyboard places the pose too.
        if (e.detail === 0 && this.view.tool === tool) this.view.startKeyboardTool();
      });
    }
    this.follow = document.getElementById("tool-follow");
    this.follow.addEventListener("click", () => this.view.setFollow(!this.view.following));
    view.canvas.addEventListener("followchange", (e) => this.follow.setAttribute("aria-pressed", String(e.detail.on)));
    // Escape stops following, and turns a tool off, wherever the focus is (the map handles its
    // own tool's Escape, with the mark).
    document.addEventListener("keydown", (e) => {
      if (e.key === "Escape" && this.view.following && !document.querySelector("dialog[open]")) this.view.setFollow(false);
      if (e.key !== "Escape" || e.defaultPrevented || this.view.tool === "pan") return;
      if (e.target === this.view.canvas || document.querySelector("dialog[open]")) return;
      this.cancel();
    });
    document.getElementById("zoom-in").addEventListener("click", () => view.zoomBy(1.25));
    document.getElementById("zoom-out").addEventListener("click", () => view.zoomBy(0.8));
    document.getElementById("zoom-fit").addEventListener("click", () => view.fit());
    live.addEventListener("change", (e) => {
      if (e.detail.topic === "robots") this._refresh();
      if (e.detail.topic === "blocks") view.requestDraw(); // blocked tables are drawn crossed
      if (e.detail.topic.startsWith("pose:") || e.detail.topic === "robots") this._forgetReachedGoals();
    });
    selection.onChange(() => {
      this._setTool("pan");
      this._refresh();
      view.requestDraw(); // following: the newly selected robot comes to the middle
    });
    this._legend();
    onLangChange(() => {
      this._refresh();
      this._showHint(this.view.tool);
    });
    this._refresh();
  }

  /** The keyboard's mark moved: the hint (a live region) says where it is now. */
  showMark(mark) {
    if (!mark || !TOOLS[this.view.tool]) return;
    const where = t("map.where", {
      x: mark.x.toFixed(2),
      y: mark.y.toFixed(2),
      heading: Math.round((mark.yaw * 180) / Math.PI),
    });
    this.hint.textContent = `${t("map.hintFor", { robot: this.selection.name, hint: t("map.keysHint") })} ${where}`;
  }

  /** Escape on the map: the tool is off, focus back on its button. */
  cancel() {
    const button = TOOLS[this.view.tool] && document.getElementById(TOOLS[this.view.tool].button);
    this._setTool("pan");
    if (button) button.focus();
  }

  _setTool(tool) {
    this.view.setTool(tool);
    for (const [name, { button }] of Object.entries(TOOLS)) {
      document.getElementById(button).setAttribute("aria-pressed", String(name === tool));
    }
    this._showHint(tool);
  }

  _showHint(tool) {
    const hint = TOOLS[tool] && TOOLS[tool].hint;
    this.hint.textContent = hint ? t("map.hintFor", { robot: this.selection.name, hint: t(hint) }) : "";
  }

  /** The legend's swatches in the colours the map draws with; never taller than the map. */
  _legend() {
    const legend = document.getElementById("map-legend");
    for (const sw of legend.querySelectorAll("[data-status]")) sw.style.background = statusColour(sw.dataset.status);
    for (const sw of legend.querySelectorAll("[data-kind]")) sw.style.background = WAYPOINT_COLOURS[sw.dataset.kind];
    const fit = () => {
      const h = this.view.canvas.clientHeight;
      legend.style.maxHeight = h > 0 ? `${Math.max(44, h - 16)}px` : "";
    };
    new ResizeObserver(fit).observe(this.view.canvas);
    legend.addEventListener("toggle", fit);
  }

  _refresh() {
    this.follow.disabled = !this.selection.name;
    const robot = this.live.robots.get(this.selection.name);
    for (const [tool, { button }] of Object.entries(TOOLS)) {
      const ok = Boolean(robot && allowed(robot.status, tool));
      const b = document.getElementById(button);
      b.disabled = !ok;
      b.title = ok ? t(TOOLS[tool].hint) : t("map.needManual");
      if (!ok && this.view.tool === tool) this._setTool("pan");
    }
  }

  async posePicked(tool, pose) {
    const name = this.selection.name;
    const fromKeys = document.activeElement === this.view.canvas;
    this._setTool("pan"); // one-shot, as in RViz: the next drag pans again
    if (fromKeys) document.getElementById(TOOLS[tool].button).focus(); // focus kept on the tool
    if (!name) return;
    let yaw = pose.yaw;
    if (yaw === null) {
      // A tap without a drag keeps the robot's current heading.
      const now = this.live.pose(name);
      yaw = now ? now.yaw : 0;
    }
    const msg = { clientmsg: "control", robot: name, action: tool, x: pose.x, y: pose.y, yaw };
    const reply = await act(null, () => this.conn.request(msg));
    if (!reply) return;
    const where = t("map.where", {
      x: pose.x.toFixed(2),
      y: pose.y.toFixed(2),
      heading: Math.round((yaw * 180) / Math.PI),
    });
    if (tool === "goal") {
      this.goals.set(name, { x: pose.x, y: pose.y, yaw });
      toast(t("map.moving", { robot: name, where }));
    } else {
      toast(t("map.calibrated", { robot: name, where }));
    }
    this.view.requestDraw();
  }

  _forgetReachedGoals() {
    for (const [name, goal] of this.goals) {
      const robot = this.live.robots.get(name);
      const p = this.live.pose(name);
      const reached = p && Math.hypot(p.x - goal.x, p.y - goal.y) < REACHED_M;
      if (!robot || robot.status !== "Manual" || reached) this.goals.delete(name);
    }
  }
}
