// The setup page's places step: the restaurant's map (drawn by the console's own map modules,
// js/map/), on which the owner puts the kitchen pass, each robot's home and the tables.
//
// A spot is picked by tapping the map (press and drag to say which way a robot faces there), by
// the keyboard (the map takes focus: arrow keys move a mark, [ and ] turn it, Enter picks it,
// Escape cancels: js/map/view.js), or as "where this robot stands". The owner then says what is
// there — a table (its number), the pass, a robot's home — and it is saved: `create waypoint`
// at the spot, or with `robot` (the robot's own pose); a robot's home is also given to the robot
// (`site edit_robot` `home`). Without a map yet, the step says so and sends the owner to the
// console (a new tab), and shows the map as soon as one comes (the `map` topic).

import { MapView } from "../map/view.js";
import { byName, confirmDialog, describeError, el, KeyedList } from "../ui.js";
import { onLangChange, statusName, t } from "../i18n.js";
import { show } from "./steps.js";

const NO_GOALS = new Map();

/** The pass, the tables and who has a home, from the live state. */
export function placesState(live) {
  const wps = [...live.waypoints.values()];
  const pass = wps.find((w) => w.kind === "pass") || null;
  const tables = wps.filter((w) => w.kind === "table").map((w) => w.name).sort(byName);
  const robots = [...live.robots.values()].sort((a, b) => byName(a.name, b.name));
  const homes = robots.map((r) => ({ robot: r.name, home: r.home && live.waypoints.has(r.home) ? r.home : null }));
  const ready = Boolean(pass) && tables.length > 0 && robots.length > 0 && homes.every((h) => h.home);
  return { pass, tables, homes, ready };
}

function round2(v) {
  return Math.round(v * 100) / 100;
}

export class PlacesStep {
  constructor(conn, live) {
    this.conn = conn;
    this.live = live;
    this.spot = null; // {x, y, yaw} tapped on the map, or {robot} where a robot stands
    this.fromKeys = false;
    this.canvas = document.getElementById("map");
    this.view = new MapView(this.canvas, live, {
      selected: () => null,
      goals: () => NO_GOALS,
      onSelect: () => {},
      onPose: (_tool, pose) => this.pick(pose),
      onCancel: () => this.cancel(),
      onCursor: (mark) => this.sayMark(mark),
    });
    this.view.setTool("goal"); // a press (and a drag for the heading) picks a spot
    document.getElementById("places-zoom-in").addEventListener("click", () => this.view.zoomBy(1.25));
    document.getElementById("places-zoom-out").addEventListener("click", () => this.view.zoomBy(0.8));
    document.getElementById("places-zoom-fit").addEventListener("click", () => this.view.fit());
    this.pin = document.getElementById("places-pin");
    new MutationObserver(() => this.placePin()).observe(this.canvas, { attributes: true, attributeFilter: ["data-draws"] });

    this.form = document.getElementById("place-form");
    this.tableInput = document.getElementById("place-table");
    this.robotSelect = document.getElementById("place-robot");
    this.said = document.getElementById("places-said");
    this.form.addEventListener("change", () => this.enableFields());
    this.form.addEventListener("submit", (e) => {
      e.preventDefault();
      this.save();
    });
    document.getElementById("place-cancel").addEventListener("click", () => this.cancel());
    this.form.addEventListener("keydown", (e) => {
      if (e.key === "Escape" && !document.querySelector("dialog[open]")) this.cancel();
    });
    document.getElementById("places-back").addEventListener("click", () => show("robots"));
    this.doneBtn = document.getElementById("places-done");
    this.doneBtn.addEventListener("click", () => show("trip"));

    this.robotOptions = new KeyedList(this.robotSelect, {
      key: (r) => r.name,
      build: (r) => el("option", { value: r.name, text: r.name }),
    });
    this.stands = new KeyedList(document.getElementById("places-stands"), {
      key: (r) => r.name,
      signature: (r) => [r.status, Boolean(this.live.pose(r.name))],
      build: (r) => this.standsRow(r),
      empty: () => el("li", { class: "hint", text: t("setup.places.noRobots") }),
    });
    this.check = new KeyedList(document.getElementById("places-check"), {
      key: (c) => c.key,
      signature: (c) => [c.ok, c.text],
      build: (c) => el("li", { class: c.ok ? "ok" : "missing", text: c.text }),
    });
    live.addEventListener("change", (e) => {
      const topic = e.detail.topic;
      if (topic === "map" || topic === "robots" || topic === "waypoints") this.render();
      if (topic === "map" || topic === "robots" || topic === "waypoints" || topic.startsWith("pose:")) this.view.requestDraw();
    });
    onLangChange(() => {
      if (this.legend) document.getElementById("place-legend").textContent = t(...this.legend);
      this.stands.invalidate();
      this.check.invalidate();
      this.render();
      this.view.requestDraw();
    });
    this.render();
  }

  render() {
    const hasMap = Boolean(this.live.map);
    document.getElementById("places-nomap").hidden = hasMap;
    document.getElementById("places-work").hidden = !hasMap;
    const robots = [...this.live.robots.values()].sort((a, b) => byName(a.name, b.name));
    this.robotOptions.update(robots);
    this.stands.update(robots);
    const state = placesState(this.live);
    const items = [
      state.pass
        ? { key: "pass", ok: true, text: t("setup.places.checkPass", { name: state.pass.name }) }
        : { key: "pass", ok: false, text: t("setup.places.checkNoPass") },
      state.tables.length
        ? { key: "tables", ok: true, text: t("setup.places.checkTables", { count: state.tables.length, tables: state.tables.join(", ") }) }
        : { key: "tables", ok: false, text: t("setup.places.checkNoTables") },
      ...state.homes.map((h) =>
        h.home
          ? { key: `home:${h.robot}`, ok: true, text: t("setup.places.checkHome", { robot: h.robot, name: h.home }) }
          : { key: `home:${h.robot}`, ok: false, text: t("setup.places.checkNoHome", { robot: h.robot }) },
      ),
    ];
    if (!robots.length) items.push({ key: "robots", ok: false, text: t("setup.places.checkNoRobot") });
    this.check.update(items);
    this.doneBtn.disabled = !state.ready;
    if (this.spot && this.spot.robot && !this.live.robots.has(this.spot.robot)) this.cancel();
    this.placePin();
  }

  standsRow(r) {
    const offline = r.status === "Offline" || !this.live.pose(r.name);
    return el(
      "li",
      {},
      el("button", {
        type: "button",
        class: "secondary",
        disabled: offline,
        text: t("setup.places.stands", { robot: r.name }),
        onclick: (e) => this.pickRobot(r.name, e.currentTarget),
      }),
      offline ? el("span", { class: "hint", text: t("setup.places.standsOffline", { status: statusName(r.status) }) }) : null,
    );
  }

  /** A spot tapped (or picked with the keyboard) on the map: what is there? */
  pick(pose) {
    this.fromKeys = document.activeElement === this.canvas;
    this.spot = { x: pose.x, y: pose.y, yaw: pose.yaw };
    const hasPass = Boolean(placesState(this.live).pass);
    this.openForm(["setup.places.whatHere", {}], hasPass ? "table" : "pass", null);
  }

  /** "Save where this robot stands": what is there? (Its home, if it has none yet.) */
  pickRobot(robot, button) {
    this.fromKeys = false;
    this.returnTo = button;
    this.spot = { robot };
    const r = this.live.robots.get(robot);
    const homeless = !(r && r.home && this.live.waypoints.has(r.home));
    this.openForm(["setup.places.whatStands", { robot }], homeless ? "home" : "table", robot);
  }

  /** The form that names the spot: `legend` its question ([catalog key, placeholders]). */
  openForm(legend, kind, robot) {
    this.legend = legend;
    document.getElementById("place-legend").textContent = t(...legend);
    for (const box of this.form.querySelectorAll('input[name="place-kind"]')) box.checked = box.value === kind;
    this.tableInput.value = this.nextTable();
    if (robot) this.robotSelect.value = robot;
    this.enableFields();
    this.form.hidden = false;
    this.said.textContent = "";
    this.placePin();
    this.form.querySelector('input[name="place-kind"]:checked').focus();
  }

  enableFields() {
    const kind = this.kind();
    this.tableInput.disabled = kind !== "table";
    this.robotSelect.disabled = kind !== "home";
  }

  kind() {
    const box = this.form.querySelector('input[name="place-kind"]:checked');
    return box ? box.value : "table";
  }

  cancel() {
    const back = this.fromKeys ? this.canvas : this.returnTo;
    this.spot = null;
    this.returnTo = null;
    this.form.hidden = true;
    this.placePin();
    if (back && back.isConnected && !back.disabled) back.focus();
  }

  /** The next table's name: after the highest "T<n>" (or "<n>") there is, else T1. */
  nextTable() {
    let best = null;
    for (const name of placesState(this.live).tables) {
      const m = /^(\D*)(\d+)$/.exec(name);
      if (m && (!best || Number(m[2]) > best.n)) best = { prefix: m[1], n: Number(m[2]) };
    }
    return best ? `${best.prefix}${best.n + 1}` : "T1";
  }

  async save() {
    const spot = this.spot;
    if (!spot) return;
    const kind = this.kind();
    const msg = { clientmsg: "create", type: "waypoint", kind, replace: false };
    let home = null; // the robot this place is the home of
    let done;
    if (kind === "table") {
      const name = this.tableInput.value.trim();
      if (!name) {
        this.said.textContent = t("setup.places.needTable");
        this.tableInput.focus();
        return;
      }
      if (this.live.waypoints.has(name)) {
        const yes = await confirmDialog(t("setup.places.moveQuestion", { name }), {
          yes: t("setup.places.moveYes"),
          no: t("setup.places.moveNo"),
          detail: t("setup.places.moveDetail", { name }),
        });
        if (!yes) return;
        msg.replace = true;
      }
      msg.name = name;
      done = t("setup.places.savedTable", { name });
    } else if (kind === "pass") {
      const pass = placesState(this.live).pass;
      msg.name = pass ? pass.name : t("setup.places.passName"); // one pass: placed again, it moves
      msg.replace = this.live.waypoints.has(msg.name);
      done = t("setup.places.savedPass");
    } else {
      home = this.robotSelect.value;
      const r = this.live.robots.get(home);
      if (!r) return;
      msg.name = r.home && this.live.waypoints.has(r.home) ? r.home : t("setup.places.homeName", { robot: home });
      msg.replace = this.live.waypoints.has(msg.name);
      done = t("setup.places.savedHome", { robot: home });
    }
    if (spot.robot) msg.robot = spot.robot;
    else {
      msg.x = round2(spot.x);
      msg.y = round2(spot.y);
      if (spot.yaw !== null && spot.yaw !== undefined) msg.yaw = Number(spot.yaw.toFixed(4));
    }
    const saveBtn = document.getElementById("place-save");
    saveBtn.disabled = true;
    try {
      await this.conn.request(msg);
      if (home && this.live.robots.get(home).home !== msg.name) {
        await this.conn.request({ clientmsg: "site", action: "edit_robot", robot: home, home: msg.name });
      }
      const back = this.fromKeys ? this.canvas : this.returnTo;
      this.spot = null;
      this.form.hidden = true;
      this.placePin();
      this.said.textContent = done;
      if (back && back.isConnected && !back.disabled) back.focus();
    } catch (err) {
      this.said.textContent = t("setup.failed", { message: describeError(err) });
    } finally {
      saveBtn.disabled = false;
    }
  }

  /** The keyboard's mark moved: said as how far it is from the nearest place or robot. */
  sayMark(mark) {
    const out = document.getElementById("places-mark");
    if (!mark) {
      out.textContent = "";
      return;
    }
    let near = null;
    const spots = [...this.live.waypoints.values()].map((w) => [w.name, w.x, w.y]);
    for (const name of this.live.robots.keys()) {
      const p = this.live.pose(name);
      if (p) spots.push([name, p.x, p.y]);
    }
    for (const [name, x, y] of spots) {
      const d = Math.hypot(x - mark.x, y - mark.y);
      if (!near || d < near.d) near = { name, d };
    }
    out.textContent = near ? t("setup.places.markNear", { name: near.name, metres: near.d.toFixed(1) }) : t("setup.places.markAlone");
  }

  /** The spot being named, pinned on the map (where the robot stands: on the robot). */
  placePin() {
    const spot = this.spot;
    const p = spot && (spot.robot ? this.live.pose(spot.robot) : spot);
    if (!p || this.form.hidden) {
      this.pin.hidden = true;
      return;
    }
    const [sx, sy] = this.view.toScreen(p.x, p.y);
    this.pin.hidden = false;
    this.pin.style.left = `${this.canvas.offsetLeft + this.canvas.clientLeft + sx}px`;
    this.pin.style.top = `${this.canvas.offsetTop + this.canvas.clientTop + sy}px`;
  }
}
