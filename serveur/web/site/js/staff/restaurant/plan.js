// The Restaurant tab's floor plan: draw the restaurant's map from its floor plan (issue 29).
//
// The owner picks the plan's image (PNG or JPEG) and sees it at once with the walls the current
// threshold keeps shaded (a live preview done here, on the page's own copy of the image: no
// round trip while the slider moves). Then, on the plan:
//   - "Erase" / "Draw wall": drag to rub out what is not a wall (tables, text, dimension lines)
//     or to add one the plan shows faintly; each stroke is kept and sent with the request;
//   - "Measure across" / "Measure along": tap the two ends of a distance measured on the floor
//     and type it in metres (one across the room, one along it, as the design report's map was
//     made): the scale comes from them, and two scales that disagree say the plan is stretched.
// "Check the map" sends the plan (`site upload`, kind `plan`) and asks `site plan_map` for a
// preview: the map's size and whether the plan is stretched. "Use this map" applies it; the
// places now in a wall are named. "Download for the robot" saves the map as map_server's PGM and
// YAML, made here from the preview's cells (the robot's AMCL reads them).

import { describeError, el } from "../../ui.js";
import { t } from "../../i18n.js";
import { field } from "../forms.js";
import { uprightGrid } from "../../map/grid.js";
import { decodeImage, pixelAt, saveAs, sendFile } from "./upload.js";

// Each tool and its words (written out: tests/web/test_i18n.py finds every key used).
const TOOL_KEYS = {
  erase: "owner.plan.tool.erase",
  wall: "owner.plan.tool.wall",
  across: "owner.plan.tool.across",
  along: "owner.plan.tool.along",
};
const TOOLS = Object.keys(TOOL_KEYS);
const STROKE_PX = 12; // the width of an erase or wall stroke on the plan's own pixels, per 1000 px

/** The PGM (P5) and YAML map_server reads, from a map snapshot (cells -1/0/100, row 0 lowest). */
export function mapServerFiles(snap, stem = "restaurant") {
  const cells = Uint8Array.from(atob(snap.data), (c) => c.charCodeAt(0));
  const { width, height } = snap;
  const header = new TextEncoder().encode(`P5\n# CREATOR: serveur ${snap.resolution.toFixed(3)} m/pix\n${width} ${height}\n255\n`);
  const pixels = new Uint8Array(width * height);
  for (let row = 0; row < height; row++) {
    for (let col = 0; col < width; col++) {
      const v = (cells[row * width + col] << 24) >> 24; // int8
      // Image rows go down from the top; map rows go up from the bottom.
      pixels[(height - 1 - row) * width + col] = v < 0 ? 205 : v >= 65 ? 0 : 254;
    }
  }
  const pgm = new Uint8Array(header.length + pixels.length);
  pgm.set(header);
  pgm.set(pixels, header.length);
  const [x, y] = snap.origin;
  const yaml = `image: ${stem}.pgm\nresolution: ${snap.resolution}\norigin: [${x}, ${y}, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\nmode: trinary\n`;
  return { pgm, yaml };
}

function download(name, data, type) {
  const href = URL.createObjectURL(new Blob([data], { type }));
  saveAs(href, name);
  setTimeout(() => URL.revokeObjectURL(href), 1000);
}

export class PlanSection {
  constructor(conn) {
    this.conn = conn;
    this.file = null;
    this.image = null; // the plan as decoded by the browser
    this.grey = null; // its grey levels, for the live threshold
    this.strokes = [];
    this.measures = { across: null, along: null };
    this.pending = null; // the first end of a measure being tapped
    this.tool = null; // none at first: a first touch on the plan changes nothing
    this.preview = null; // the last plan_map preview's reply
    this.fileInput = el("input", { id: "plan-file", type: "file", accept: "image/png,image/jpeg", required: true });
    this.threshold = el("input", { id: "plan-threshold", type: "range", min: 0, max: 255, value: 128 });
    this.canvas = el("canvas", { class: "plan-canvas", "data-i18n-aria-label": "owner.plan.canvas", role: "img" });
    this.toolButtons = Object.fromEntries(
      TOOLS.map((tool) => [tool, el("button", { type: "button", "aria-pressed": String(tool === this.tool), "data-tool": tool, "data-i18n": TOOL_KEYS[tool], onclick: () => this._setTool(tool) })]),
    );
    this.metres = {
      across: el("input", { id: "plan-across", type: "number", min: 0.2, max: 500, step: 0.01, inputmode: "decimal" }),
      along: el("input", { id: "plan-along", type: "number", min: 0.2, max: 500, step: 0.01, inputmode: "decimal" }),
    };
    this.undoBtn = el("button", { type: "button", "data-i18n": "owner.plan.undo", onclick: () => this._undo() });
    this.checkBtn = el("button", { type: "button", "data-needs-online": true, "data-i18n": "owner.plan.check", onclick: () => this._check(false) });
    this.useBtn = el("button", { type: "button", class: "primary", "data-needs-online": true, disabled: true, "data-i18n": "owner.plan.use", onclick: () => this._check(true) });
    this.downloadBtn = el("button", { type: "button", disabled: true, "data-i18n": "owner.plan.download", onclick: () => this._download() });
    this.status = el("p", { class: "rest-plan-status", role: "status", "aria-live": "polite" });
    // The map as the robot will have it (the preview's cells), once checked: what "Use" keeps.
    this.previewCanvas = el("canvas", { class: "plan-canvas plan-preview", role: "img", "data-i18n-aria-label": "owner.plan.previewCanvas" });
    this.previewBox = el("div", { hidden: true }, el("h3", { "data-i18n": "owner.plan.previewTitle" }), this.previewCanvas, el("p", { class: "muted rest-hint", "data-i18n": "owner.plan.downloadNote" }));
    this.work = el(
      "div",
      { class: "plan-work", hidden: true },
      field("plan-threshold", "owner.plan.threshold", this.threshold),
      el("div", { class: "plan-tools", role: "group", "data-i18n-aria-label": "owner.plan.tools" }, ...TOOLS.map((tool) => this.toolButtons[tool]), this.undoBtn),
      this.canvas,
      field("plan-across", "owner.plan.acrossMetres", this.metres.across),
      field("plan-along", "owner.plan.alongMetres", this.metres.along),
      el("div", { class: "form-buttons" }, this.checkBtn, this.useBtn, this.downloadBtn),
      this.previewBox,
    );
    this.section = el(
      "section",
      { class: "card rest-plan", "aria-labelledby": "rest-plan-title" },
      el("h2", { id: "rest-plan-title", "data-i18n": "owner.plan.title" }),
      el("p", { class: "muted rest-hint", "data-i18n": "owner.plan.intro" }),
      field("plan-file", "owner.plan.file", this.fileInput),
      this.work,
      this.status,
    );
    this.fileInput.addEventListener("change", () => this._load());
    this.threshold.addEventListener("input", () => this._draw());
    this._pointer();
  }

  _say(key, params) {
    this.status.textContent = key ? t(key, params) : "";
  }

  _setTool(tool) {
    this.tool = tool;
    this.pending = null;
    for (const [name, b] of Object.entries(this.toolButtons)) b.setAttribute("aria-pressed", String(name === tool));
    this._say(tool === "across" || tool === "along" ? "owner.plan.tapEnds" : null);
  }

  /** Take back the last stroke (or, with none left, the last measure). */
  _undo() {
    if (this.strokes.length) this.strokes.pop();
    else if (this.measures.along) this.measures.along = null;
    else this.measures.across = null;
    this._draw();
  }

  async _load() {
    this.file = this.fileInput.files[0] || null;
    this.strokes = [];
    this.measures = { across: null, along: null };
    this.preview = null;
    this.useBtn.disabled = this.downloadBtn.disabled = true;
    if (!this.file) return;
    const img = await decodeImage(this.file);
    if (!img) {
      this.work.hidden = true;
      this._say("owner.plan.notImage");
      return;
    }
    this.image = img;
    const c = document.createElement("canvas");
    c.width = img.naturalWidth;
    c.height = img.naturalHeight;
    const ctx = c.getContext("2d", { willReadFrequently: true });
    ctx.drawImage(img, 0, 0);
    const rgba = ctx.getImageData(0, 0, c.width, c.height).data;
    this.grey = new Uint8Array(c.width * c.height);
    for (let i = 0; i < this.grey.length; i++) this.grey[i] = (rgba[4 * i] + rgba[4 * i + 1] + rgba[4 * i + 2]) / 3;
    this.canvas.width = c.width;
    this.canvas.height = c.height;
    this.work.hidden = false;
    this._say(null);
    this._draw();
  }

  /** The plan with the walls the threshold keeps shaded, the strokes and the measures. */
  _draw() {
    if (!this.image) return;
    const { width, height } = this.canvas;
    const ctx = this.canvas.getContext("2d");
    const out = ctx.createImageData(width, height);
    const level = Number(this.threshold.value);
    for (let i = 0; i < this.grey.length; i++) {
      const wall = this.grey[i] < level;
      out.data[4 * i] = wall ? 30 : 255;
      out.data[4 * i + 1] = wall ? 41 : 255;
      out.data[4 * i + 2] = wall ? 59 : 255;
      out.data[4 * i + 3] = 255;
    }
    ctx.putImageData(out, 0, 0);
    const w = this._strokeWidth();
    for (const s of this.strokes) {
      ctx.strokeStyle = s.kind === "erase" ? "#ffffff" : "#1e293b";
      ctx.lineWidth = s.width;
      ctx.lineCap = ctx.lineJoin = "round";
      ctx.beginPath();
      s.points.forEach(([x, y], i) => (i ? ctx.lineTo(x, y) : ctx.moveTo(x, y)));
      if (s.points.length === 1) ctx.lineTo(s.points[0][0] + 0.1, s.points[0][1]);
      ctx.stroke();
    }
    ctx.lineWidth = Math.max(2, w / 4);
    for (const [kind, m] of Object.entries(this.measures)) {
      if (!m) continue;
      ctx.strokeStyle = kind === "across" ? "#2563eb" : "#c026d3";
      ctx.beginPath();
      ctx.moveTo(...m.a);
      ctx.lineTo(...m.b);
      ctx.stroke();
    }
    this.canvas.dataset.strokes = String(this.strokes.length);
    this.canvas.dataset.measures = Object.values(this.measures).filter(Boolean).length.toString();
  }

  _strokeWidth() {
    return Math.max(4, Math.round((STROKE_PX * Math.max(this.canvas.width, this.canvas.height)) / 1000));
  }

  _pointer() {
    let drawing = null;
    this.canvas.addEventListener("pointerdown", (e) => {
      if (!this.image || !this.tool) return;
      const p = pixelAt(this.canvas, e);
      if (this.tool === "across" || this.tool === "along") {
        if (!this.pending) {
          this.pending = p;
          this._say("owner.plan.tapOther");
        } else {
          this.measures[this.tool] = { a: this.pending, b: p };
          this.pending = null;
          this._say("owner.plan.typeMetres");
          this.metres[this.tool].focus();
          this._draw();
        }
        return;
      }
      this.canvas.setPointerCapture(e.pointerId);
      drawing = { kind: this.tool, points: [p], width: this._strokeWidth() };
      this.strokes.push(drawing);
      this._draw();
    });
    this.canvas.addEventListener("pointermove", (e) => {
      if (!drawing || drawing.points.length >= 500) return;
      drawing.points.push(pixelAt(this.canvas, e));
      this._draw();
    });
    const end = () => {
      drawing = null;
    };
    this.canvas.addEventListener("pointerup", end);
    this.canvas.addEventListener("pointercancel", end);
  }

  _request(apply) {
    const measure = (kind) => {
      const m = this.measures[kind];
      const metres = Number(this.metres[kind].value);
      if (!m || !(metres > 0.1)) return null;
      return { a: m.a, b: m.b, metres };
    };
    const across = measure("across");
    const along = measure("along");
    if (!across || !along) return null;
    return {
      clientmsg: "site",
      action: "plan_map",
      threshold: Number(this.threshold.value),
      strokes: this.strokes.slice(0, 200),
      across,
      along,
      apply,
    };
  }

  async _check(apply) {
    const msg = this._request(apply);
    if (!msg) {
      this._say("owner.plan.needMeasures");
      return;
    }
    this.checkBtn.disabled = this.useBtn.disabled = true;
    try {
      // Sent again for each try: an upload is used up once it became the map.
      msg.upload = await sendFile(this.conn, this.file, "plan", (percent) => this._say("owner.map.sending", { percent }));
      this._say("owner.map.checking");
      const reply = await this.conn.request(msg);
      this.preview = reply;
      const m = reply.map;
      const size = { width: (m.width * m.resolution).toFixed(1), height: (m.height * m.resolution).toFixed(1), cm: Math.round(m.resolution * 100) };
      const parts = [t(apply ? "owner.map.done" : "owner.plan.previewed", size)];
      if (reply.plan.stretched) parts.push(t("owner.plan.stretched", { percent: (reply.plan.disagreement * 100).toFixed(1) }));
      if (apply && reply.outside.length) parts.push(t("owner.map.outside", { places: reply.outside.join(", ") }));
      this.status.textContent = parts.join(" ");
      this._drawPreview(reply.plan.map);
      this.downloadBtn.disabled = false;
      this.useBtn.disabled = apply;
    } catch (err) {
      const reason = err.details && err.details.reason;
      this._say("owner.map.refused", { why: reason === "not_an_image" ? t("owner.plan.notImage") : describeError(err) });
      this.useBtn.disabled = !this.preview;
    } finally {
      this.checkBtn.disabled = false;
    }
  }

  /** The previewed map's cells, the right way up (their rows go up from the bottom). */
  _drawPreview(map) {
    this.previewCanvas.width = map.width;
    this.previewCanvas.height = map.height;
    this.previewCanvas.getContext("2d").drawImage(uprightGrid(map), 0, 0);
    this.previewBox.hidden = false;
    this.previewCanvas.dataset.cells = `${map.width}x${map.height}`;
  }

  _download() {
    if (!this.preview) return;
    const { pgm, yaml } = mapServerFiles(this.preview.plan.map);
    download("restaurant.yaml", yaml, "text/yaml");
    download("restaurant.pgm", pgm, "image/x-portable-graymap");
  }
}
