// The selected robot's camera beside the joystick. Watched only while staff drive the robot
// (it is under manual control) and the page is shown: nothing is pulled over the robot's Wi-Fi
// otherwise. The newest picture is drawn and its age said; a picture more than half a second
// old is "stale": the joystick (teleop.js asks fresh()) stops the robot, because driving on a
// frozen picture is how robots hit people. A robot without a camera is driven on the map.

import { el } from "../ui.js";
import { allowed } from "../status.js";
import { onLangChange, t } from "../i18n.js";

/** A picture older than this (ms, on arrival plus since) must not be driven on. */
export const STALE_MS = 500;
const TICK_MS = 100;

export class CameraView extends EventTarget {
  constructor(conn, live, selection) {
    super();
    this.conn = conn;
    this.live = live;
    this.selection = selection;
    this.robot = null; // the robot watched
    this.state = "off"; // off | starting | none | disabled | live | stale
    this.arrived = 0; // performance.now() of the last picture
    this.ageOnArrival = 0; // ms the picture was old when it arrived
    this.url = null; // the picture shown
    this.pending = null; // the newest picture, being decoded
    this.img = el("img", { class: "camera-picture", alt: "", hidden: "" });
    // The state is announced when it changes; the age, redrawn ten times a second, is not.
    this.caption = el("span", { role: "status" });
    this.age = el("span", { class: "camera-age" });
    this.node = el(
      "figure",
      { class: "camera", hidden: "" },
      this.img,
      el("figcaption", { class: "camera-state" }, this.caption, " ", this.age),
    );
    this.timer = null;
    conn.addEventListener("camera", (e) => this._picture(e.detail.buffer));
    conn.addEventListener("state", (e) => e.detail.state === "online" && this._resync(true));
    live.addEventListener("change", (e) => {
      if (e.detail.topic === "robots") this._resync();
      else if (e.detail.topic === "settings") this._resync(true); // cameras switched on or off
    });
    selection.onChange(() => this._resync());
    document.addEventListener("visibilitychange", () => this._resync());
    onLangChange(() => this._say());
  }

  /** May the robot be driven on what the page shows? (No camera: yes, on the map.) */
  fresh() {
    if (this.state === "off" || this.state === "none" || this.state === "disabled") return true;
    return this.state === "live" && this._ageMs() <= STALE_MS;
  }

  _wanted() {
    const name = this.selection.name;
    const robot = name && this.live.robots.get(name);
    if (!robot || document.hidden || !allowed(robot.status, "teleop")) return null;
    return name;
  }

  async _resync(again = false) {
    const want = this._wanted();
    if (want === this.robot && !again) return;
    const old = this.robot;
    this.robot = want;
    if (old && old !== want) {
      this.conn.request({ clientmsg: "camera", robot: old, watch: false }).catch(() => {});
    }
    this._set(want ? "starting" : "off");
    if (!want) return;
    try {
      const reply = await this.conn.request({ clientmsg: "camera", robot: want, watch: true });
      if (this.robot !== want) return;
      if (reply.camera.state === "none") this._set("none");
      if (reply.camera.state === "off") this._set("disabled"); // the owner switched cameras off
    } catch {
      if (this.robot === want) this._set("none");
    }
  }

  _picture(buffer) {
    const view = new DataView(buffer);
    const n = view.getUint16(0);
    let header;
    try {
      header = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 2, n)));
    } catch {
      return;
    }
    if (header.camera !== this.robot) return; // a picture still on its way from the last robot
    // Decoded off screen first, then shown: the picture on screen never blanks between two,
    // and a newer picture arriving meanwhile wins (the older one is dropped).
    const url = URL.createObjectURL(new Blob([new Uint8Array(buffer, 2 + n)], { type: "image/jpeg" }));
    this.pending = url;
    const next = new Image();
    next.src = url;
    next
      .decode()
      .then(() => {
        if (this.pending !== url) return URL.revokeObjectURL(url);
        const previous = this.url;
        this.url = url;
        this.img.src = url;
        if (previous) URL.revokeObjectURL(previous);
      })
      .catch(() => URL.revokeObjectURL(url));
    this.arrived = performance.now();
    this.ageOnArrival = 1000 * (header.age + (header.lag ?? 0));
    this.img.hidden = false;
    this._set("live");
  }

  _ageMs() {
    return performance.now() - this.arrived + this.ageOnArrival;
  }

  _tick() {
    if (this.state === "live" && this._ageMs() > STALE_MS) this._set("stale");
    else this._say();
  }

  _set(state) {
    const was = this.state;
    this.state = state;
    this.node.hidden = state === "off";
    if (!(state === "live" || state === "stale")) this.img.hidden = true;
    const ticking = state === "live" || state === "stale";
    if (ticking && !this.timer) this.timer = setInterval(() => this._tick(), TICK_MS);
    if (!ticking && this.timer) {
      clearInterval(this.timer);
      this.timer = null;
    }
    this._say();
    if (was !== state) this.dispatchEvent(new CustomEvent("change", { detail: { state } }));
  }

  _say() {
    const robot = this.robot || "";
    const age = (this._ageMs() / 1000).toFixed(1);
    this.img.alt = t("camera.alt", { robot });
    const key = {
      starting: "camera.starting",
      none: "camera.none",
      disabled: "camera.disabled",
      live: "camera.live",
      stale: "camera.stale",
    }[this.state];
    const text = key ? t(key, { robot }) : "";
    if (this.caption.textContent !== text) this.caption.textContent = text;
    const shown = this.state === "live" || this.state === "stale" ? t("camera.age", { age }) : "";
    if (this.age.textContent !== shown) this.age.textContent = shown;
    this.node.dataset.state = this.state;
  }
}
