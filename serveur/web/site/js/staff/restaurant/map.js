// The Restaurant tab's map: replace the restaurant's map with the two files a robot's map_saver
// wrote (its YAML and its PGM or PNG image). The files are sent in parts (upload.js), then
// `site set_map` checks them and makes them the map; the places now in a wall are named so the
// owner moves them. A refused file says why in the owner's words, and nothing changes.

import { describeError, el } from "../../ui.js";
import { t } from "../../i18n.js";
import { field } from "../forms.js";
import { sendFile } from "./upload.js";

const REASONS = {
  outside: "owner.map.reason.outside",
  mismatch: "owner.map.reason.mismatch",
  not_a_map: "owner.map.reason.notAMap",
  too_large: "owner.map.reason.tooLarge",
};

export class MapSection {
  constructor(conn) {
    this.conn = conn;
    this.yamlInput = el("input", { id: "map-yaml", type: "file", accept: ".yaml,.yml", required: true });
    this.imageInput = el("input", { id: "map-image", type: "file", accept: ".pgm,.png,image/png,image/x-portable-graymap", required: true });
    this.useBtn = el("button", { type: "submit", class: "primary", "data-needs-online": true, "data-i18n": "owner.map.use" });
    this.progress = el("p", { class: "rest-map-progress", role: "status", "aria-live": "polite" });
    const form = el(
      "form",
      { class: "rest-map", "data-i18n-aria-label": "owner.map.title" },
      el("p", { class: "muted rest-hint", "data-i18n": "owner.map.intro" }),
      field("map-yaml", "owner.map.yaml", this.yamlInput),
      field("map-image", "owner.map.image", this.imageInput),
      el("div", { class: "form-buttons" }, this.useBtn),
      this.progress,
    );
    form.addEventListener("submit", (e) => {
      e.preventDefault();
      if (form.reportValidity()) this._use();
    });
    this.section = el(
      "section",
      { class: "card", "aria-labelledby": "rest-map-title" },
      el("h2", { id: "rest-map-title", "data-i18n": "owner.map.title" }),
      form,
    );
  }

  _say(key, params) {
    this.progress.textContent = t(key, params);
  }

  async _use() {
    const [yaml, image] = [this.yamlInput.files[0], this.imageInput.files[0]];
    if (!yaml || !image) return;
    this.useBtn.disabled = true;
    try {
      const sending = (percent) => this._say("owner.map.sending", { percent });
      const y = await sendFile(this.conn, yaml, "map_yaml", sending);
      const i = await sendFile(this.conn, image, "map_image", sending);
      this._say("owner.map.checking");
      const reply = await this.conn.request({ clientmsg: "site", action: "set_map", yaml: y, image: i });
      const m = reply.map;
      const size = { width: (m.width * m.resolution).toFixed(1), height: (m.height * m.resolution).toFixed(1), cm: Math.round(m.resolution * 100) };
      this.progress.textContent = reply.outside.length
        ? `${t("owner.map.done", size)} ${t("owner.map.outside", { places: reply.outside.join(", ") })}`
        : t("owner.map.done", size);
    } catch (err) {
      const reason = err.details && err.details.reason;
      this._say("owner.map.refused", { why: reason && REASONS[reason] ? t(REASONS[reason]) : describeError(err) });
    } finally {
      this.useBtn.disabled = false;
    }
  }
}
