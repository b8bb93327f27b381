// The Restaurant tab's site settings: time at a table (or for ever), trays per robot, leaving
// without Go, the cameras, the target wait (what the Statistics tab's forecast aims at), the
// languages the pages offer and the default one, and what robots do besides delivering
// (modesettings.js: calls, plates, charging, cruising) (`site set_settings`). Its own
// module so that the panel (restaurant.js) only lays the sections out; the form keeps the
// owner's unsaved changes when the settings change elsewhere.

import { act, el, toast } from "../../ui.js";
import { LANGS, t } from "../../i18n.js";
import { field } from "../forms.js";
import { ModeFields } from "./modesettings.js";

export const MAX_TRAYS = 12;
const TARGET_MINUTES = [1, 60]; // the target wait the server accepts (60-3600 s), in minutes

export class SettingsSection {
  /** `onTrays()`: the site's trays changed (the robots' rows show them). */
  constructor(conn, onTrays) {
    this.conn = conn;
    this.onTrays = onTrays;
    this.settings = null; // the settings as last read or saved
    this.dirty = false; // the settings form holds the owner's unsaved changes
    this.timeout = el("input", { id: "set-timeout", type: "number", min: 10, max: 3600, step: 1, inputmode: "numeric", required: true });
    this.forever = el("input", { id: "set-forever", type: "checkbox" });
    this.trays = el("input", { id: "set-trays", type: "number", min: 1, max: MAX_TRAYS, step: 1, inputmode: "numeric", required: true });
    this.autoDepart = el("input", { id: "set-auto", type: "checkbox" });
    this.cameras = el("input", { id: "set-cameras", type: "checkbox" });
    this.target = el("input", { id: "set-target", type: "number", min: TARGET_MINUTES[0], max: TARGET_MINUTES[1], step: 1, inputmode: "numeric", required: true });
    this.langBoxes = Object.fromEntries(LANGS.map((l) => [l, el("input", { id: `set-lang-${l}`, type: "checkbox", value: l })]));
    this.language = el("select", { id: "set-language" });
    this.modes = new ModeFields();
    this.saveBtn = el("button", { type: "submit", class: "primary", "data-needs-online": true, "data-i18n": "owner.settings.save" });
    const form = el(
      "form",
      { class: "rest-settings", "data-i18n-aria-label": "owner.settings.title" },
      field("set-timeout", "owner.settings.timeout", this.timeout),
      el("label", { class: "check" }, this.forever, el("span", { "data-i18n": "owner.settings.forever" })),
      el("p", { class: "muted rest-hint", "data-i18n": "owner.settings.timeoutNote" }),
      field("set-trays", "owner.settings.trays", this.trays),
      el("label", { class: "check" }, this.autoDepart, el("span", { "data-i18n": "owner.settings.autoDepart" })),
      el("p", { class: "muted rest-hint", "data-i18n": "owner.settings.autoDepartNote" }),
      el("label", { class: "check" }, this.cameras, el("span", { "data-i18n": "owner.settings.cameras" })),
      el("p", { class: "muted rest-hint", "data-i18n": "owner.settings.camerasNote" }),
      field("set-target", "owner.settings.target", this.target),
      el("p", { class: "muted rest-hint", "data-i18n": "owner.settings.targetNote" }),
      el(
        "fieldset",
        { class: "rest-langs" },
        el("legend", { "data-i18n": "owner.settings.languages" }),
        ...LANGS.map((l) => el("label", { class: "check" }, this.langBoxes[l], el("span", { lang: l === "zh" ? "zh-Hans" : l, "data-i18n": `lang.${l}` }))),
      ),
      field("set-language", "owner.settings.language", this.language),
      ...this.modes.nodes,
      el("div", { class: "form-buttons" }, this.saveBtn),
    );
    form.addEventListener("submit", (e) => {
      e.preventDefault();
      if (form.reportValidity()) this._save();
    });
    form.addEventListener("input", () => {
      this.dirty = true;
      this._sync();
    });
    this.form = form;
    this.section = el(
      "section",
      { class: "card", "aria-labelledby": "rest-settings-title" },
      el("h2", { id: "rest-settings-title", "data-i18n": "owner.settings.title" }),
      form,
    );
  }

  /** The site's trays per robot, null until the settings are read. */
  siteTrays() {
    return this.settings ? this.settings.trays : null;
  }

  /** Settings read or saved: the form shows them, unless it holds unsaved changes (`force`: it
   *  is the owner's own save). */
  got(settings, { force = false } = {}) {
    if (!settings) return;
    const traysChanged = !this.settings || this.settings.trays !== settings.trays;
    this.settings = settings;
    if (traysChanged) this.onTrays();
    if (this.dirty && !force) return;
    this.dirty = false;
    const forever = settings.table_timeout === null || settings.table_timeout === undefined;
    this.forever.checked = forever;
    this.timeout.value = forever ? "" : String(Math.round(settings.table_timeout));
    this.trays.value = String(settings.trays);
    this.autoDepart.checked = Boolean(settings.auto_depart);
    this.cameras.checked = settings.cameras !== false;
    this.target.value = String(Math.round((settings.target_wait ?? 600) / 60));
    for (const l of LANGS) this.langBoxes[l].checked = settings.languages.includes(l);
    this.fillLanguage(settings.language);
    this.modes.fill(settings);
    this._sync();
  }

  /** The default language picks among the languages ticked; "for ever" needs no seconds. */
  _sync() {
    this.timeout.disabled = this.forever.checked;
    this.timeout.required = !this.forever.checked;
    const ticked = LANGS.filter((l) => this.langBoxes[l].checked);
    // At least one language: the last one ticked cannot be unticked.
    for (const l of LANGS) this.langBoxes[l].disabled = ticked.length === 1 && this.langBoxes[l].checked;
    this.fillLanguage();
  }

  fillLanguage(want = null) {
    const keep = want || this.language.value;
    const ticked = LANGS.filter((l) => this.langBoxes[l].checked);
    const shown = ticked.length ? ticked : LANGS;
    this.language.replaceChildren(...shown.map((l) => el("option", { value: l, text: t(`lang.${l}`) })));
    this.language.value = shown.includes(keep) ? keep : shown[0];
  }

  async _save() {
    const languages = LANGS.filter((l) => this.langBoxes[l].checked);
    const msg = {
      clientmsg: "site",
      action: "set_settings",
      table_timeout: this.forever.checked ? null : Number(this.timeout.value),
      trays: Number(this.trays.value),
      auto_depart: this.autoDepart.checked,
      cameras: this.cameras.checked,
      target_wait: Number(this.target.value) * 60,
      languages,
      language: this.language.value,
      ...this.modes.values(),
    };
    const reply = await act(this.saveBtn, () => this.conn.request(msg));
    if (!reply) return;
    this.dirty = false;
    this.got(reply.settings, { force: true });
    toast(t("owner.settings.saved"));
  }
}
