// Teleop for the selected robot: an on-screen joystick (x/y for omni robots; forward/turn for
// differential ones), a rotation pad, and the keyboard. While anything is held the command is
// re-sent at 5 Hz (the robot stops by itself when commands stop coming); on release one zero
// command is sent so it stops at once.

import { act, el, showError } from "../ui.js";
import { allowed } from "../status.js";
import { onLangChange, t } from "../i18n.js";

const PERIOD_MS = 200;
const V_MAX = 0.5; // m/s
const W_MAX = 1.2; // rad/s
const KEYS = {
  // key: [forward, left, turn-left] in -1..1
  w: [1, 0, 0], ArrowUp: [1, 0, 0],
  s: [-1, 0, 0], ArrowDown: [-1, 0, 0],
  a: [0, 1, 0], d: [0, -1, 0],
  q: [0, 0, 1], ArrowLeft: [0, 0, 1],
  e: [0, 0, -1], ArrowRight: [0, 0, -1],
};

export class Teleop {
  /** ``camera``: the selected robot's camera (camera.js); a stale picture stops the robot. */
  constructor(root, conn, live, selection, camera) {
    this.conn = conn;
    this.live = live;
    this.selection = selection;
    this.camera = camera;
    this.stick = [0, 0]; // joystick: right, up in -1..1
    this.turn = 0; // rotation pad: right in -1..1
    this.keys = new Set();
    this.timer = null;
    this.target = null; // the robot being driven; fixed while a command is held

    this.note = el("p", { class: "muted teleop-note" });
    this.joystick = pad("teleop.joystick", "joystick");
    this.rotor = pad("teleop.rotor", "rotor");
    // The way out beside the pads: on a phone the robot's card is below the map while driving.
    this.done = el("button", {
      class: "secondary teleop-done",
      type: "button",
      "data-needs-online": true,
      "data-i18n": "teleop.done",
      hidden: true,
      onclick: (e) => act(e.currentTarget, () => this.conn.request({ clientmsg: "ready", robot: this.selection.name })),
    });
    root.append(
      el(
        "section",
        { class: "teleop", "aria-labelledby": "teleop-title" },
        el("h3", { id: "teleop-title", "data-i18n": "teleop.title" }),
        this.note,
        el("div", { class: "drive" }, camera.node, el("div", { class: "pads" }, this.joystick.node, this.rotor.node)),
        el("p", { class: "hint", "data-i18n": "teleop.keys" }),
        this.done,
      ),
    );
    dragPad(this.joystick, (x, y) => this._input(() => (this.stick = [x, y])));
    dragPad(this.rotor, (x) => this._input(() => (this.turn = x)), true);
    document.addEventListener("keydown", (e) => this._key(e, true));
    document.addEventListener("keyup", (e) => this._key(e, false));
    // Losing focus must never leave a robot driving on a stale "key held".
    window.addEventListener("blur", () => this._releaseAll());
    document.addEventListener("visibilitychange", () => document.hidden && this._releaseAll());
    live.addEventListener("change", (e) => e.detail.topic === "robots" && this._refresh());
    selection.onChange(() => {
      this._releaseAll();
      this._refresh();
    });
    onLangChange(() => this._refresh());
    // The picture went stale while driving: stop now, not at the next command.
    camera.addEventListener("change", () => {
      if (!camera.fresh()) {
        if (this.timer) this._stale();
      } else this._refresh(); // a fresh picture again: the note says who is driven
    });
    this._refresh();
  }

  _stale() {
    this._releaseAll(); // one zero twist
    this.note.textContent = t("teleop.stale");
  }

  _enabled() {
    const robot = this.live.robots.get(this.selection.name);
    return Boolean(robot && allowed(robot.status, "teleop"));
  }

  _refresh() {
    const on = this._enabled();
    for (const p of [this.joystick, this.rotor]) p.node.setAttribute("aria-disabled", String(!on));
    this.note.textContent = on ? t("teleop.driving", { robot: this.selection.name }) : t("teleop.needManual");
    this.done.hidden = !on;
    if (on) this.done.setAttribute("aria-label", t("teleop.doneFor", { robot: this.selection.name }));
    // A phone or a portrait tablet puts the map and these pads first while a robot is driven.
    document.body.dataset.driving = String(on);
    if (!on && this.timer) this._releaseAll();
  }

  _key(e, down) {
    if (!(e.key in KEYS) || e.ctrlKey || e.metaKey || e.altKey) return;
    const t = e.target;
    if (t && (t.isContentEditable || ["INPUT", "TEXTAREA", "SELECT"].includes(t.tagName))) return;
    if (t && t.getAttribute && t.getAttribute("role") === "tab") return; // arrows move between tabs
    // The focused map takes the arrow keys (pan, or the Calibrate / Move here mark): W/A/S/D/Q/E drive.
    if (t && t.id === "map" && e.key.startsWith("Arrow")) return;
    if (document.getElementById("panel-map").hidden || document.querySelector("dialog[open]")) return;
    if (!this._enabled() && down) return;
    if (e.key.startsWith("Arrow")) e.preventDefault(); // no page scrolling while driving
    if (down === this.keys.has(e.key)) return; // key repeat
    this._input(() => (down ? this.keys.add(e.key) : this.keys.delete(e.key)));
  }

  _input(change) {
    change();
    const cmd = this._command();
    const moving = cmd.vx || cmd.vy || cmd.wz;
    if (moving && !this.timer) {
      if (!this._enabled()) return this._releaseAll();
      if (!this.camera.fresh()) return this._stale();
      this.target = this.selection.name;
      this._send(cmd);
      this.timer = setInterval(() => this._send(this._command()), PERIOD_MS);
    } else if (!moving && this.timer) {
      this._stop();
    }
  }

  _command() {
    let [fwd, left, turn] = [this.stick[1], 0, -this.turn];
    const diff = this.live.robots.get(this.selection.name)?.kinematics === "diff";
    if (diff) turn += -this.stick[0]; // one stick drives a differential robot: forward and turn
    else left += -this.stick[0];
    for (const k of this.keys) {
      const [f, l, t] = KEYS[k];
      fwd += f;
      if (diff) turn += l + t;
      else {
        left += l;
        turn += t;
      }
    }
    const clamp = (v) => Math.max(-1, Math.min(1, v));
    return { vx: round(clamp(fwd) * V_MAX), vy: round(clamp(left) * V_MAX), wz: round(clamp(turn) * W_MAX) };
  }

  _send(cmd) {
    const robot = this.target;
    if (!robot) return;
    if ((cmd.vx || cmd.vy || cmd.wz) && !this.camera.fresh()) return this._stale();
    const msg = { clientmsg: "control", robot, action: "teleop", ...cmd };
    this.conn.request(msg).catch((err) => {
      showError(err);
      if (cmd.vx || cmd.vy || cmd.wz) this._releaseAll();
    });
  }

  _stop() {
    clearInterval(this.timer);
    this.timer = null;
    this._send({ vx: 0, vy: 0, wz: 0 });
    this.target = null;
  }

  _releaseAll() {
    this.keys.clear();
    this.stick = [0, 0];
    this.turn = 0;
    this.joystick.reset();
    this.rotor.reset();
    if (this.timer) this._stop();
  }
}

function round(v) {
  return Math.round(v * 1000) / 1000 || 0; // never "-0"
}

function pad(labelKey, kind) {
  const knob = el("div", { class: "knob" });
  const node = el("div", { class: `pad ${kind}`, role: "group", "data-i18n-aria-label": labelKey }, knob);
  return {
    node,
    knob,
    reset() {
      knob.style.transform = "";
    },
  };
}

/** Pointer dragging on a pad reports (right, up) in -1..1; releasing reports (0, 0). */
function dragPad(p, report, horizontalOnly = false) {
  let active = null;
  const update = (ev) => {
    const r = p.node.getBoundingClientRect();
    const half = Math.min(r.width, r.height) / 2;
    let x = (ev.clientX - (r.left + r.width / 2)) / half;
    let y = horizontalOnly ? 0 : -(ev.clientY - (r.top + r.height / 2)) / half;
    const len = Math.hypot(x, y);
    if (len > 1) [x, y] = [x / len, y / len];
    p.knob.style.transform = `translate(${x * half * 0.7}px, ${-y * half * 0.7}px)`;
    report(x, y);
  };
  p.node.addEventListener("pointerdown", (ev) => {
    if (p.node.getAttribute("aria-disabled") === "true") return;
    active = ev.pointerId;
    p.node.setPointerCapture(ev.pointerId);
    update(ev);
  });
  p.node.addEventListener("pointermove", (ev) => ev.pointerId === active && update(ev));
  const end = (ev) => {
    if (ev.pointerId !== active) return;
    active = null;
    p.reset();
    report(0, 0);
  };
  p.node.addEventListener("pointerup", end);
  p.node.addEventListener("pointercancel", end);
}
