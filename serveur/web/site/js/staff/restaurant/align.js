// The Restaurant tab's "floor plan under the map" (issue 29): the robot drives on the map it made
// itself (its own origin, heading and scale); the owner knows the room from its floor plan. Here
// the owner marks the same spot — a corner, a pillar, a door — on the plan and then on the
// robot's map, two spots or more; `site align_map` fits the plan onto the map (scale, turn,
// shift) and says how far each spot is off, the map here shows the plan laid over it, and "Use"
// sends the plan so that every screen draws it under the map: places tapped on it then land
// where the robot will find them.
//
// The plan is decoded by this page (the server never decodes pictures); the map is the `map`
// topic's grid, drawn here the right way up (its rows go up from the bottom).

import { describeError, el } from "../../ui.js";
import { t } from "../../i18n.js";
import { field } from "../forms.js";
import { uprightGrid } from "../../map/grid.js";
import { decodeImage, pixelAt, sendFile } from "./upload.js";

const COLORS = ["#2563eb", "#c026d3", "#16a34a", "#ea580c", "#0891b2", "#be123c"];

/** Draw numbered markers at canvas points `ps` ([[x, y] | null]). */
function markers(ctx, ps, size) {
  ctx.save();
  ctx.font = `bold ${Math.round(size * 1.4)}px system-ui, sans-serif`;
  ctx.textBaseline = "middle";
  ps.forEach((p, i) => {
    if (!p) return;
    ctx.fillStyle = ctx.strokeStyle = COLORS[i % COLORS.length];
    ctx.lineWidth = Math.max(1, size / 4);
    ctx.beginPath();
    ctx.arc(p[0], p[1], size, 0, 2 * Math.PI);
    ctx.stroke();
    ctx.fillText(String(i + 1), p[0] + size * 1.3, p[1]);
  });
  ctx.restore();
}

export class AlignSection {
  constructor(conn, live) {
    this.conn = conn;
    this.live = live;
    this.image = null;
    this.file = null;
    this.pairs = []; // {plan: [c, r], map: [x, y] | null}
    this.fit = null; // the last align_map reply's alignment
    this._gridOf = null;
    this._grid = null;
    this.fileInput = el("input", { id: "align-file", type: "file", accept: "image/png,image/jpeg", required: true });
    this.planCanvas = el("canvas", { class: "plan-canvas", role: "img", "data-i18n-aria-label": "owner.align.planCanvas" });
    this.mapCanvas = el("canvas", { class: "plan-canvas align-map", role: "img", "data-i18n-aria-label": "owner.align.mapCanvas" });
    this.undoBtn = el("button", { type: "button", "data-i18n": "owner.align.undo", onclick: () => this._undo() });
    this.checkBtn = el("button", { type: "button", "data-needs-online": true, "data-i18n": "owner.align.check", onclick: () => this._send(false) });
    this.useBtn = el("button", { type: "button", class: "primary", "data-needs-online": true, disabled: true, "data-i18n": "owner.align.use", onclick: () => this._send(true) });
    this.status = el("p", { class: "rest-plan-status", role: "status", "aria-live": "polite" });
    this.work = el(
      "div",
      { class: "plan-work", hidden: true },
      el("div", { class: "align-pair" }, el("div", {}, el("h3", { "data-i18n": "owner.align.onPlan" }), this.planCanvas), el("div", {}, el("h3", { "data-i18n": "owner.align.onMap" }), this.mapCanvas)),
      el("div", { class: "form-buttons" }, this.undoBtn, this.checkBtn, this.useBtn),
    );
    this.section = el(
      "section",
      { class: "card rest-plan rest-align", "aria-labelledby": "rest-align-title" },
      el("h2", { id: "rest-align-title", "data-i18n": "owner.align.title" }),
      el("p", { class: "muted rest-hint", "data-i18n": "owner.align.intro" }),
      field("align-file", "owner.align.file", this.fileInput),
      this.work,
      this.status,
    );
    this.fileInput.addEventListener("change", () => this._load());
    this.planCanvas.addEventListener("pointerdown", (e) => this._tapPlan(e));
    this.mapCanvas.addEventListener("pointerdown", (e) => this._tapMap(e));
  }

  _say(key, params) {
    this.status.textContent = key ? t(key, params) : "";
  }

  /** The map changed (the `map` topic): draw it again; a new map of the room drops the spots. */
  mapChanged() {
    if (this.live.map && this._gridOf && this.live.map.data !== this._gridOf.data) {
      this.pairs = [];
      this.fit = null;
      this.useBtn.disabled = true;
    }
    this._draw();
  }

  async _load() {
    this.file = this.fileInput.files[0] || null;
    this.pairs = [];
    this.fit = null;
    this.useBtn.disabled = true;
    if (!this.file) return;
    const img = await decodeImage(this.file);
    if (!img) {
      this.work.hidden = true;
      return this._say("owner.plan.notImage");
    }
    this.image = img;
    this.planCanvas.width = img.naturalWidth;
    this.planCanvas.height = img.naturalHeight;
    this.work.hidden = false;
    this._say(this.live.map ? "owner.align.tapPlan" : "owner.align.noMap", { n: 1 });
    this._draw();
  }

  _tapPlan(e) {
    if (!this.image || !this.live.map) return;
    const last = this.pairs[this.pairs.length - 1];
    if (last && !last.map) last.plan = pixelAt(this.planCanvas, e); // tapped again: moved
    else this.pairs.push({ plan: pixelAt(this.planCanvas, e), map: null });
    this._changed("owner.align.tapMap");
  }

  _tapMap(e) {
    const map = this.live.map;
    const last = this.pairs[this.pairs.length - 1];
    if (!map || !last || last.map) return this._say("owner.align.planFirst");
    const [cx, cy] = pixelAt(this.mapCanvas, e);
    last.map = [map.origin[0] + cx * map.resolution, map.origin[1] + (map.height - cy) * map.resolution].map((v) => Math.round(v * 1000) / 1000);
    this._changed("owner.align.tapPlan");
  }

  _undo() {
    const last = this.pairs[this.pairs.length - 1];
    if (last && last.map) last.map = null;
    else this.pairs.pop();
    this._changed("owner.align.tapPlan");
  }

  _changed(next) {
    this.fit = null;
    this.useBtn.disabled = true;
    this._say(next, { n: this.pairs.filter((p) => p.map).length + 1 });
    this._draw();
  }

  _points() {
    return this.pairs.filter((p) => p.map).map((p) => ({ plan: p.plan, map: p.map }));
  }

  async _send(apply) {
    const points = this._points();
    if (points.length < 2) return this._say("owner.align.twoSpots");
    const button = apply ? this.useBtn : this.checkBtn;
    button.disabled = true;
    try {
      const msg = { clientmsg: "site", action: "align_map", points };
      if (apply) msg.upload = await sendFile(this.conn, this.file, "plan", (percent) => this._say("owner.map.sending", { percent }));
      const reply = await this.conn.request(apply ? { ...msg, apply: true } : msg);
      this.fit = reply.alignment;
      const worst = this.fit.residuals.indexOf(Math.max(...this.fit.residuals));
      const cm = (m) => Math.round(m * 100);
      const words = t("owner.align.fits", { cm: cm(this.fit.rms), spot: worst + 1, worst: cm(this.fit.residuals[worst]) });
      this.status.textContent = apply ? `${words} ${t("owner.align.used")}` : words;
      this.useBtn.disabled = false;
    } catch (err) {
      const field = err.details && err.details.field;
      const reason = err.details && err.details.reason;
      const why =
        reason === "mismatch" ? t("owner.align.mismatch")
        : field === "points" ? t("owner.align.tooClose")
        : field === "upload" ? t("owner.plan.notImage")
        : err.code === "conflict" && !(err.details && err.details.upload) ? t("owner.align.noMap")
        : describeError(err);
      this._say("owner.align.refused", { why });
    } finally {
      button.disabled = false;
      this.useBtn.disabled = !this.fit;
      this._draw();
    }
  }

  _draw() {
    if (!this.image) return;
    const pc = this.planCanvas.getContext("2d");
    pc.drawImage(this.image, 0, 0);
    const size = Math.max(6, Math.round(Math.max(this.planCanvas.width, this.planCanvas.height) / 80));
    markers(pc, this.pairs.map((p) => p.plan), size);
    this.planCanvas.dataset.spots = String(this.pairs.length);
    const map = this.live.map;
    if (!map) return;
    if (this._gridOf !== map) {
      this._grid = uprightGrid(map);
      this._gridOf = map;
      this.mapCanvas.width = map.width;
      this.mapCanvas.height = map.height;
    }
    const mc = this.mapCanvas.getContext("2d");
    mc.drawImage(this._grid, 0, 0);
    if (this.fit) {
      // The plan laid over the map as fitted: world = scale * R * (column, -row) + shift.
      const { scale, rotation, tx, ty } = this.fit;
      const r = map.resolution;
      mc.save();
      mc.globalAlpha = 0.45;
      mc.setTransform(1 / r, 0, 0, -1 / r, -map.origin[0] / r, map.height + map.origin[1] / r);
      mc.transform(scale * Math.cos(rotation), scale * Math.sin(rotation), -scale * Math.sin(rotation), scale * Math.cos(rotation), tx, ty);
      mc.scale(1, -1);
      mc.drawImage(this.image, 0, 0);
      mc.restore();
    }
    const toCanvas = (p) => p && [(p[0] - map.origin[0]) / map.resolution, map.height - (p[1] - map.origin[1]) / map.resolution];
    markers(mc, this.pairs.map((p) => toCanvas(p.map)), Math.max(3, Math.round(Math.max(map.width, map.height) / 80)));
    this.mapCanvas.dataset.spots = String(this._points().length);
    this.mapCanvas.dataset.fitted = String(Boolean(this.fit));
  }
}
