// The map toolbar: Calibrate (initialpose) and Move here (goal) as one-shot press-and-drag
// tools like RViz's 2D Pose Estimate / 2D Nav Goal, and zoom buttons. From the keyboard, a tool
// button pressed with Enter or Space puts a cursor on the map (view.js: arrow keys move it, [ and
// ] turn it, Enter confirms, Escape cancels); focus then returns to the tool's button.
// Follow robot (aria-pressed) keeps the selected robot in the middle of the map (view.js
// setFollow); a pan or zoom by hand, or Escape anywhere, turns it off.
// The map's legend (staff.html #map-legend) takes its swatches' colours from the drawing code
// and is kept no taller than the map.
//
// Zones (issue 21): the owner's "Draw zone" tool (view.js's "zone" tool: corners clicked or
// placed from the keyboard, Finish or Enter on the last corner closes it, Escape cancels), then
// a form asks the zone's name and capacity and sends `create zone`; redrawing an existing zone
// (editZone, from the Restaurant tab's list) sends it with `replace`. The side panel lists the
// zones with who holds and who waits for each, and staff break a lease stuck on a robot pushed
// out of the zone by hand (Release, `release`).

import { act, byName, el, KeyedList, toast } from "../ui.js";
import { allowed, statusColour } from "../status.js";
import { WAYPOINT_COLOURS, ZONE_COLOURS, zoneState } from "../map/draw.js";
import { onLangChange, t } from "../i18n.js";
import { field, formDialog } from "./forms.js";
import { leaseWords, releaseButtons } from "./leases.js";
import { nearWords, spotWords } from "./near.js";

// hint: a catalog key.
const TOOLS = {
  initialpose: { button: "tool-calibrate", hint: "map.calibrateHintFull" },
  goal: { button: "tool-goal", hint: "map.goalHintFull" },
};
const REACHED_M = 0.3;
const MAX_CAPACITY = 8;

export class MapTools {
  constructor(conn, live, view, selection, goals) {
    this.conn = conn;
    this.live = live;
    this.view = view;
    this.selection = selection;
    this.goals = goals;
    this.hint = document.getElementById("tool-hint");
    this.editing = null; // the zone being drawn again (replace), or null for a new one
    this.zoneButton = document.getElementById("tool-zone");
    this.finishButton = document.getElementById("tool-zone-finish");
    this.zoneButton.addEventListener("click", (e) => {
      this.editing = null;
      this._setTool(this.view.tool === "zone" ? "pan" : "zone");
      if (e.detail === 0 && this.view.tool === "zone") this.view.startKeyboardTool();
    });
    this.finishButton.addEventListener("click", () => {
      if (!this.view.finishZone()) this._showHint("zone");
    });
    conn.addEventListener("session", () => this._showOwnerTools());
    // The Restaurant tab's "Draw again" (restaurant.js): the map, with this zone's drawing started.
    document.addEventListener("serveur:redraw-zone", (e) => this.editZone(e.detail.zone));
    // The view calls back with the zone tool's corners (main.js made it with the pose tools' hooks).
    view.opts.onZone = (points) => this.zoneDrawn(points);
    view.opts.onDraft = () => this.showDraft();
    this._zonesPanel();
    conn.subscribe(["zones", "leases"]);
    for (const [tool, { button }] of Object.entries(TOOLS)) {
      document.getElementById(button).addEventListener("click", (e) => {
        this._setTool(this.view.tool === tool ? "pan" : tool);
        // detail 0: pressed from the keyboard, so the keyboard places the pose too.
        if (e.detail === 0 && this.view.tool === tool) this.view.startKeyboardTool();
      });
    }
    // "Where it may be": the selected robot's localisation particles, streamed only while
    // shown — pressed, or while the selected robot is not sure where it is (what staff need to
    // see when they set where it is).
    this.cloudButton = document.getElementById("tool-cloud");
    this.cloudPressed = false;
    this.cloudTopic = null;
    this.cloudButton.addEventListener("click", () => {
      this.cloudPressed = !this.cloudPressed;
      this._syncCloud();
    });
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
      if (e.detail.topic === "zones" || e.detail.topic === "leases") {
        view.requestDraw(); // zones are drawn tinted by their leases
        this._renderZones();
      }
      if (e.detail.topic.startsWith("pose:") || e.detail.topic === "robots") this._forgetReachedGoals();
    });
    selection.onChange(() => {
      if (this.view.tool !== "zone") this._setTool("pan");
      this._refresh();
      view.requestDraw(); // following: the newly selected robot comes to the middle
    });
    this._legend();
    onLangChange(() => {
      this._refresh();
      this._showHint(this.view.tool);
      this.zoneRows.invalidate();
      this._renderZones();
    });
    this._refresh();
    this._showOwnerTools();
  }

  /** Drawing zones is the owner's (the server refuses anyone else): the tool shows for owners. */
  _showOwnerTools() {
    const owner = Boolean(this.conn.session && this.conn.session.role === "owner");
    this.zoneButton.hidden = !owner;
    if (!owner && this.view.tool === "zone") this._setTool("pan");
  }

  /** Draw zone `name` again: its corners are replaced, its name kept. */
  editZone(name) {
    if (!this.live.zones.has(name)) return;
    document.getElementById("tab-map").click();
    this.editing = name;
    this._setTool("zone");
    this.zoneButton.focus();
  }

  /** The zone tool's polygon is closed: ask its name and capacity, then store it. */
  async zoneDrawn(points) {
    const editing = this.editing;
    const old = editing ? this.live.zones.get(editing) : null;
    this.editing = null;
    this._setTool("pan");
    const name = el("input", { id: "zone-name", type: "text", maxlength: 64, required: true, autocomplete: "off", value: editing || "" });
    if (editing) name.readOnly = true;
    const capacity = el("input", {
      id: "zone-capacity", type: "number", min: 1, max: MAX_CAPACITY, step: 1, inputmode: "numeric", required: true,
      value: String(old ? old.capacity : 1),
    });
    // Where a robot standing in the zone waits when it cannot go on (docs/zones.md): a place.
    const waitAt = el("select", { id: "zone-wait-at" }, el("option", { value: "", text: t("map.zone.waitNone") }));
    for (const wp of [...this.live.waypoints.values()].sort((a, b) => a.name.localeCompare(b.name))) {
      waitAt.append(el("option", { value: wp.name, text: wp.name }));
    }
    waitAt.value = old && old.wait_at ? old.wait_at : "";
    await formDialog({
      title: editing ? t("map.zone.editTitle", { zone: editing }) : t("map.zone.newTitle"),
      yes: t("map.zone.save"),
      fields: [
        field("zone-name", "map.zone.name", name),
        field("zone-capacity", "map.zone.capacity", capacity),
        field("zone-wait-at", "map.zone.waitAt", waitAt),
        el("p", { class: "muted rest-hint", text: t("map.zone.corners", { count: points.length }) }),
        el("p", { class: "muted rest-hint", text: t("map.zone.capacityNote") }),
      ],
      submit: async () => {
        const msg = {
          clientmsg: "create",
          type: "zone",
          name: name.value.trim(),
          points,
          capacity: Number(capacity.value),
          replace: Boolean(editing),
        };
        if (waitAt.value) msg.wait_at = waitAt.value;
        const reply = await this.conn.request(msg);
        toast(t("map.zone.saved", { zone: reply.zone.name }));
        return true;
      },
    });
    this.zoneButton.focus(); // the keyboard's place kept: the tool again, for the next zone
  }

  /** The side panel's Zones: each zone, its state, who holds it, who waits; Release. */
  _zonesPanel() {
    this.zoneList = el("ul", { class: "zones-list", "data-i18n-aria-label": "zones.title" });
    this.zoneSection = el(
      "section",
      { class: "zones-side", "aria-labelledby": "zones-title", hidden: true },
      el("h2", { id: "zones-title", "data-i18n": "zones.title" }),
      this.zoneList,
    );
    // Last in the side panel: the robots and the selected robot's joystick keep their places.
    document.querySelector("#panel-map .side").append(this.zoneSection);
    this.zoneRows = new KeyedList(this.zoneList, {
      key: (z) => z.name,
      signature: (z) => [z.capacity, this.live.leases.get(z.name) || null],
      build: (z) => this._zoneRow(z),
    });
  }

  _renderZones() {
    const zones = [...this.live.zones.values()].sort((a, b) => byName(a.name, b.name));
    this.zoneSection.hidden = zones.length === 0;
    this.zoneRows.update(zones);
  }

  _zoneRow(z) {
    const lease = this.live.leases.get(z.name);
    const state = zoneState(lease);
    return el(
      "li",
      { class: "zone-row", "data-zone": z.name, "data-state": state },
      el("span", { class: "zone-swatch", "aria-hidden": "true", style: { background: ZONE_COLOURS[state] } }),
      el("span", { class: "zone-name", text: z.name }),
      el("span", { class: "zone-capacity muted", text: t("zones.capacity", { count: z.capacity }) }),
      el("span", { class: "zone-lease", "data-testid": "zone-lease", text: leaseWords(lease) }),
      el("div", { class: "zone-actions" }, releaseButtons(this.conn, z.name, lease)),
    );
  }

  /** The keyboard's mark moved: the hint (a live region) says where it is now. */
  showMark(mark) {
    if (mark && this.view.tool === "zone") {
      const count = this.view.draft ? this.view.draft.length : 0;
      const where = t("map.zone.at", { where: nearWords(this.live.waypoints.values(), mark.x, mark.y) });
      this.hint.textContent = `${t("map.zone.keysHint")} ${t("map.zone.cornersSoFar", { count })} ${where}`;
      return;
    }
    if (!mark || !TOOLS[this.view.tool]) return;
    const where = t("map.where", { where: spotWords(this.live.waypoints.values(), mark.x, mark.y, mark.yaw) });
    this.hint.textContent = `${t("map.hintFor", { robot: this.selection.name, hint: t("map.keysHint") })} ${where}`;
  }

  /** Escape on the map: the tool is off, focus back on its button. */
  cancel() {
    if (this.view.tool === "zone") {
      this.editing = null;
      this._setTool("pan");
      this.zoneButton.focus();
      return;
    }
    const button = TOOLS[this.view.tool] && document.getElementById(TOOLS[this.view.tool].button);
    this._setTool("pan");
    if (button) button.focus();
  }

  _setTool(tool) {
    this.view.setTool(tool);
    for (const [name, { button }] of Object.entries(TOOLS)) {
      document.getElementById(button).setAttribute("aria-pressed", String(name === tool));
    }
    this.zoneButton.setAttribute("aria-pressed", String(tool === "zone"));
    this.finishButton.hidden = tool !== "zone";
    this._showHint(tool);
  }

  /** The zone tool: a corner added or taken back; the hint counts them. */
  showDraft() {
    if (this.view.tool === "zone") this._showHint("zone");
  }

  _showHint(tool) {
    if (tool === "zone") {
      const count = this.view.draft ? this.view.draft.length : 0;
      const what = this.editing ? t("map.zone.hintEdit", { zone: this.editing }) : t("map.zone.hint");
      this.hint.textContent = `${what} ${t("map.zone.cornersSoFar", { count })}`;
      return;
    }
    const hint = TOOLS[tool] && TOOLS[tool].hint;
    this.hint.textContent = hint ? t("map.hintFor", { robot: this.selection.name, hint: t(hint) }) : "";
  }

  /** The legend's swatches in the colours the map draws with; never taller than the map. */
  _legend() {
    const legend = document.getElementById("map-legend");
    for (const sw of legend.querySelectorAll("[data-status]")) sw.style.background = statusColour(sw.dataset.status);
    for (const sw of legend.querySelectorAll("[data-kind]")) sw.style.background = WAYPOINT_COLOURS[sw.dataset.kind];
    for (const sw of legend.querySelectorAll("[data-zone-state]")) {
      sw.style.borderColor = ZONE_COLOURS[sw.dataset.zoneState];
      sw.style.backgroundColor = `${ZONE_COLOURS[sw.dataset.zoneState]}40`; // translucent, as drawn
    }
    const fit = () => {
      const h = this.view.canvas.clientHeight;
      legend.style.maxHeight = h > 0 ? `${Math.max(44, h - 16)}px` : "";
    };
    new ResizeObserver(fit).observe(this.view.canvas);
    legend.addEventListener("toggle", fit);
  }

  /** Subscribe to the selected robot's cloud while it is shown; unsubscribe and forget it when not. */
  _syncCloud() {
    const name = this.selection.name;
    const robot = name && this.live.robots.get(name);
    const shown = Boolean(robot && (this.cloudPressed || robot.lost));
    const topic = shown ? `cloud:${name}` : null;
    this.cloudButton.disabled = !name;
    this.cloudButton.setAttribute("aria-pressed", String(shown));
    if (topic === this.cloudTopic) return;
    if (this.cloudTopic) {
      this.conn.unsubscribe([this.cloudTopic]);
      this.live.clouds.delete(this.cloudTopic.slice("cloud:".length));
      this.view.requestDraw();
    }
    this.cloudTopic = topic;
    if (topic) this.conn.subscribe([topic]);
  }

  _refresh() {
    this._syncCloud();
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
    const where = spotWords(this.live.waypoints.values(), pose.x, pose.y, yaw);
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
