// Restaurant (the owner's): the robots (address, ROS, drive, home, trays, status, why the server
// cannot reach one; edit, remove), the tables and places (rename, move, remove after seeing what
// depends on them) and the site's settings (time at a table, trays, leaving without Go, the
// languages the pages offer). Everything goes through the protocol's `site` verb (the server
// refuses anyone but an owner) and `create waypoint` with `replace` for a move.
//
// The page also follows the `settings` topic (every role may read it): the language pickers
// offer the site's languages and a device with no choice of its own speaks the site's default.
//
// Zones (issue 21): each zone with its capacity, who holds it and who waits; draw it again on the
// map (maptools.js, `create zone` with `replace`), remove it (`site remove_zone`), release a lease
// stuck on a robot (`release`), and import a file of zones ({"zones": [{name, points,
// capacity}]}: each sent as `create zone` with `replace`, those refused listed with the reason).

import { act, byName, confirmDialog, describeError, el, KeyedList, showError, toast } from "../ui.js";
import { applySiteLanguages, LANGS, onLangChange, statusName, t } from "../i18n.js";
import { leaseWords, releaseButtons } from "./maptools.js";

const KINDS = ["table", "home", "pass", "other"];
const KINEMATICS = { omni: "owner.drive.omni", diff: "owner.drive.diff" };
const MAX_TRAYS = 12;

function fixed(v, digits = 2) {
  return v === null || v === undefined || !Number.isFinite(Number(v)) ? "?" : Number(v).toFixed(digits);
}

function degrees(rad) {
  return Math.round((Number(rad) * 180) / Math.PI);
}

/** Degrees as the wire's yaw: radians in (-pi, pi]. */
function radians(deg) {
  let r = (Number(deg) * Math.PI) / 180;
  while (r > Math.PI) r -= 2 * Math.PI;
  while (r <= -Math.PI) r += 2 * Math.PI;
  return Number(r.toFixed(4));
}

function rosOf(robot) {
  return (robot.link && robot.link.ros) === "2" ? "2" : "1";
}

/** A modal form: resolves with true when submitted (and `submit` did not return false). */
export function formDialog({ title, fields, yes, danger = false, submit }) {
  return new Promise((resolve) => {
    const titleId = `dlg-${Math.random().toString(36).slice(2)}`;
    const yesBtn = el("button", { type: "submit", class: danger ? "danger" : "primary", "data-needs-online": true, text: yes });
    const noBtn = el("button", { type: "button", class: "secondary", text: t("owner.cancel") });
    const why = el("p", { class: "rest-error", role: "alert" });
    const form = el("form", { class: "rest-form", method: "dialog" }, ...fields, why, el("div", { class: "dialog-buttons" }, noBtn, yesBtn));
    const dialog = el("dialog", { class: "confirm rest-dialog", "aria-labelledby": titleId }, el("h2", { id: titleId }, title), form);
    const finish = (answer) => {
      dialog.close();
      dialog.remove();
      resolve(answer);
    };
    form.addEventListener("submit", async (e) => {
      e.preventDefault();
      if (!form.reportValidity() || yesBtn.disabled) return;
      why.textContent = "";
      yesBtn.disabled = true;
      try {
        if (await submit()) finish(true);
      } catch (err) {
        why.textContent = describeError(err); // the server's refusal, in the form it refuses
      } finally {
        yesBtn.disabled = false;
      }
    });
    noBtn.addEventListener("click", () => finish(false));
    dialog.addEventListener("cancel", (e) => {
      e.preventDefault();
      finish(false);
    });
    document.body.append(dialog);
    dialog.showModal();
    const first = form.querySelector("input, select");
    (first || noBtn).focus();
  });
}

export function field(id, labelKey, control, hint = null) {
  return el("div", { class: "rest-field" }, el("label", { for: id, "data-i18n": labelKey }), control, hint);
}

export class RestaurantPanel {
  constructor(root, conn, live) {
    this.root = root;
    this.conn = conn;
    this.live = live;
    this.settings = null; // the settings as last read or saved
    this.dirty = false; // the settings form holds the owner's unsaved changes

    // -- robots
    this.robotList = el("ul", { class: "rest-list", "data-i18n-aria-label": "owner.robots.title" });
    this.robotRows = new KeyedList(this.robotList, {
      key: (r) => r.name,
      signature: (r) => [r.url, r.link, r.kinematics, r.home, r.trays, r.status, r.link_error, r.current_task, this._siteTrays()],
      build: (r) => this._robotRow(r),
      empty: () => el("li", { class: "muted", text: t("owner.robots.none") }),
    });

    // -- tables and places
    this.placeList = el("ul", { class: "rest-list", "data-i18n-aria-label": "owner.places.title" });
    this.placeRows = new KeyedList(this.placeList, {
      key: (w) => w.name,
      signature: (w) => [w.kind, w.x, w.y, w.yaw],
      build: (w) => this._placeRow(w),
      empty: () => el("li", { class: "muted", text: t("owner.places.none") }),
    });

    // -- zones
    this.zoneList = el("ul", { class: "rest-list", "data-i18n-aria-label": "owner.zones.title" });
    this.zoneRows = new KeyedList(this.zoneList, {
      key: (z) => z.name,
      signature: (z) => [z.capacity, z.points, this.live.leases.get(z.name) || null],
      build: (z) => this._zoneRow(z),
      empty: () => el("li", { class: "muted", text: t("owner.zones.none") }),
    });
    this.zoneFile = el("input", { id: "zone-file", type: "file", accept: ".json,application/json", "data-needs-online": true });
    this.zoneFile.addEventListener("change", () => this._importZones());
    this.importReport = el("div", { class: "zone-import-report", role: "status", "data-testid": "zone-import" });

    // -- settings
    this.timeout = el("input", { id: "set-timeout", type: "number", min: 10, max: 3600, step: 1, inputmode: "numeric", required: true });
    this.forever = el("input", { id: "set-forever", type: "checkbox" });
    this.trays = el("input", { id: "set-trays", type: "number", min: 1, max: MAX_TRAYS, step: 1, inputmode: "numeric", required: true });
    this.autoDepart = el("input", { id: "set-auto", type: "checkbox" });
    this.langBoxes = Object.fromEntries(LANGS.map((l) => [l, el("input", { id: `set-lang-${l}`, type: "checkbox", value: l })]));
    this.language = el("select", { id: "set-language" });
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
      el(
        "fieldset",
        { class: "rest-langs" },
        el("legend", { "data-i18n": "owner.settings.languages" }),
        ...LANGS.map((l) => el("label", { class: "check" }, this.langBoxes[l], el("span", { lang: l === "zh" ? "zh-Hans" : l, "data-i18n": `lang.${l}` }))),
      ),
      field("set-language", "owner.settings.language", this.language),
      el("div", { class: "form-buttons" }, this.saveBtn),
    );
    form.addEventListener("submit", (e) => {
      e.preventDefault();
      if (form.reportValidity()) this._saveSettings();
    });
    form.addEventListener("input", () => {
      this.dirty = true;
      this._syncSettingsForm();
    });
    this.settingsForm = form;

    root.append(
      el(
        "div",
        { class: "rest-grid" },
        el(
          "section",
          { class: "card", "aria-labelledby": "rest-robots-title" },
          el("h2", { id: "rest-robots-title", "data-i18n": "owner.robots.title" }),
          el("p", { class: "muted", "data-i18n": "owner.robots.note" }),
          this.robotList,
        ),
        el(
          "section",
          { class: "card", "aria-labelledby": "rest-places-title" },
          el("h2", { id: "rest-places-title", "data-i18n": "owner.places.title" }),
          el("p", { class: "muted", "data-i18n": "owner.places.note" }),
          this.placeList,
        ),
        el(
          "section",
          { class: "card", "aria-labelledby": "rest-zones-title" },
          el("h2", { id: "rest-zones-title", "data-i18n": "owner.zones.title" }),
          el("p", { class: "muted", "data-i18n": "owner.zones.note" }),
          this.zoneList,
          el(
            "div",
            { class: "rest-field zone-import" },
            el("label", { for: "zone-file", "data-i18n": "owner.zones.import" }),
            this.zoneFile,
            el("p", { class: "muted rest-hint", "data-i18n": "owner.zones.importNote" }),
          ),
          this.importReport,
        ),
        el(
          "section",
          { class: "card", "aria-labelledby": "rest-settings-title" },
          el("h2", { id: "rest-settings-title", "data-i18n": "owner.settings.title" }),
          form,
        ),
      ),
    );

    conn.subscribe(["settings"]);
    live.addEventListener("change", (e) => {
      const topic = e.detail.topic;
      if (topic === "robots" || topic === "waypoints" || topic === "zones" || topic === "leases") this.render();
      if (topic === "settings") {
        applySiteLanguages(live.settings);
        this._gotSettings(live.settings);
      }
    });
    onLangChange(() => {
      this.robotRows.invalidate();
      this.placeRows.invalidate();
      this.zoneRows.invalidate();
      this._fillLanguage();
      this.render();
    });
    this._fillLanguage();
    this.render();
  }

  /** The tab was opened: the lists are live; read the settings afresh. */
  async shown() {
    this.render();
    try {
      const reply = await this.conn.request({ clientmsg: "site", action: "settings" });
      this._gotSettings(reply.settings); // a form the owner began filling meanwhile is kept
    } catch (err) {
      if (err && err.code !== "forbidden") showError(err);
    }
  }

  _siteTrays() {
    return this.settings ? this.settings.trays : null;
  }

  render() {
    this.robotRows.update([...this.live.robots.values()].sort((a, b) => byName(a.name, b.name)));
    this.placeRows.update(
      [...this.live.waypoints.values()].sort((a, b) => KINDS.indexOf(a.kind) - KINDS.indexOf(b.kind) || byName(a.name, b.name)),
    );
    this.zoneRows.update([...this.live.zones.values()].sort((a, b) => byName(a.name, b.name)));
  }

  // -- zones ----------------------------------------------------------------------------------

  _zoneRow(z) {
    const lease = this.live.leases.get(z.name);
    return el(
      "li",
      { "data-zone": z.name, class: "rest-place rest-zone" },
      el("span", { class: "rest-name", text: z.name }),
      el("span", { class: "rest-kind", text: t("owner.zones.capacity", { count: z.capacity }) }),
      el("span", { class: "muted rest-pos", text: t("owner.zones.corners", { count: z.points.length }) }),
      el("span", { class: "rest-lease", "data-testid": "zone-lease", text: leaseWords(lease) }),
      el(
        "div",
        { class: "row-actions" },
        ...releaseButtons(this.conn, z.name, lease),
        el("button", {
          class: "secondary",
          "data-needs-online": true,
          "aria-label": t("owner.zones.redrawFor", { zone: z.name }),
          text: t("owner.zones.redraw"),
          onclick: () => document.dispatchEvent(new CustomEvent("serveur:redraw-zone", { detail: { zone: z.name } })),
        }),
        el("button", {
          class: "danger",
          "data-needs-online": true,
          "aria-label": t("owner.zones.removeFor", { zone: z.name }),
          text: t("owner.remove"),
          onclick: (e) => this._removeZone(z.name, e.currentTarget),
        }),
      ),
    );
  }

  async _removeZone(zone, button) {
    const yes = await confirmDialog(t("owner.zones.removeQuestion", { zone }), {
      detail: t("owner.zones.removeDetail"),
      yes: t("owner.remove"),
      no: t("owner.cancel"),
    });
    if (!yes) return;
    const reply = await act(button, () => this.conn.request({ clientmsg: "site", action: "remove_zone", zone }));
    if (reply) toast(t("owner.zones.removed", { zone }));
  }

  /** The file chosen: each of its zones stored (replacing one of the same name); what failed said. */
  async _importZones() {
    const file = this.zoneFile.files && this.zoneFile.files[0];
    if (!file) return;
    this.importReport.replaceChildren();
    let zones;
    try {
      const doc = JSON.parse(await file.text());
      zones = Array.isArray(doc) ? doc : doc && doc.zones;
      if (!Array.isArray(zones)) throw new Error(t("owner.zones.importNoZones"));
    } catch (err) {
      this.importReport.append(el("p", { class: "rest-error", text: t("owner.zones.importUnreadable", { file: file.name, error: err.message || String(err) }) }));
      this.zoneFile.value = "";
      return;
    }
    const done = [];
    const failed = [];
    for (const [i, z] of zones.entries()) {
      const name = z && typeof z.name === "string" && z.name ? z.name : t("owner.zones.importNth", { n: i + 1 });
      const msg = { clientmsg: "create", type: "zone", name: z && z.name, points: z && z.points, replace: true };
      if (z && z.capacity !== undefined) msg.capacity = z.capacity;
      try {
        await this.conn.request(msg);
        done.push(name);
      } catch (err) {
        failed.push([name, describeError(err)]);
      }
    }
    this.zoneFile.value = "";
    this.importReport.append(el("p", { text: t("owner.zones.imported", { count: done.length, zones: done.join(", ") || "-" }) }));
    if (failed.length) {
      this.importReport.append(
        el("p", { class: "rest-error", text: t("owner.zones.importFailed", { count: failed.length }) }),
        el("ul", { class: "rest-deps" }, ...failed.map(([n, why]) => el("li", { text: t("owner.zones.importWhy", { zone: n, error: why }) }))),
      );
    }
    toast(t("owner.zones.imported", { count: done.length, zones: done.join(", ") || "-" }), { kind: failed.length ? "error" : "info" });
  }

  // -- robots ---------------------------------------------------------------------------------

  _robotRow(r) {
    const trays = r.trays === null || r.trays === undefined ? t("owner.robots.traysSite", { count: this._siteTrays() ?? "?" }) : String(r.trays);
    const detail = (key, value) => el("div", {}, el("dt", { text: t(key) }), el("dd", { text: value }));
    return el(
      "li",
      { "data-robot": r.name, class: "rest-robot" },
      el(
        "div",
        { class: "rest-head" },
        el("span", { class: "rest-name", text: r.name }),
        el("span", { class: "rest-status", text: statusName(r.status) }),
      ),
      el(
        "dl",
        { class: "rest-details" },
        detail("owner.robots.address", r.url),
        detail("owner.robots.ros", t("owner.ros.n", { n: rosOf(r) })),
        detail("owner.robots.drive", t(KINEMATICS[r.kinematics] || "owner.drive.omni")),
        detail("owner.robots.home", r.home || t("owner.robots.noHome")),
        detail("owner.robots.trays", trays),
      ),
      r.link_error ? el("p", { class: "rest-error", "data-testid": "link-error", text: t("owner.robots.linkError", { error: r.link_error }) }) : null,
      r.current_task !== null && r.current_task !== undefined
        ? el("p", { class: "muted", text: t("owner.robots.onTrip", { trip: r.current_task }) })
        : null,
      el(
        "div",
        { class: "row-actions" },
        el("button", {
          class: "secondary",
          "data-needs-online": true,
          "aria-label": t("owner.robots.editFor", { name: r.name }),
          text: t("owner.edit"),
          onclick: () => this._editRobot(r.name),
        }),
        el("button", {
          class: "danger",
          "data-needs-online": true,
          "aria-label": t("owner.robots.removeFor", { name: r.name }),
          text: t("owner.remove"),
          onclick: (e) => this._removeRobot(r.name, e.currentTarget),
        }),
      ),
    );
  }

  async _editRobot(name) {
    const r = this.live.robots.get(name);
    if (!r) return;
    const url = el("input", { id: "er-url", type: "text", required: true, autocomplete: "off", spellcheck: "false", pattern: "wss?://.+", value: r.url });
    const homes = [...this.live.waypoints.values()].sort((a, b) => (a.kind === "home" ? 0 : 1) - (b.kind === "home" ? 0 : 1) || byName(a.name, b.name));
    const home = el(
      "select",
      { id: "er-home" },
      el("option", { value: "", text: t("owner.robots.noHome") }),
      ...homes.map((w) => el("option", { value: w.name, text: w.kind === "home" ? w.name : t("owner.places.nameKind", { name: w.name, kind: t(`wp.kind.${w.kind}`) }) })),
    );
    home.value = r.home || "";
    const drive = el("select", { id: "er-drive" }, ...Object.entries(KINEMATICS).map(([v, key]) => el("option", { value: v, text: t(key) })));
    drive.value = r.kinematics;
    const ros = el("select", { id: "er-ros" }, ...["1", "2"].map((n) => el("option", { value: n, text: t("owner.ros.n", { n }) })));
    ros.value = rosOf(r);
    const trays = el(
      "select",
      { id: "er-trays" },
      el("option", { value: "", text: t("owner.robots.traysSite", { count: this._siteTrays() ?? "?" }) }),
      ...Array.from({ length: MAX_TRAYS }, (_, i) => el("option", { value: String(i + 1), text: String(i + 1) })),
    );
    trays.value = r.trays === null || r.trays === undefined ? "" : String(r.trays);
    const onTrip = r.current_task !== null && r.current_task !== undefined;
    await formDialog({
      title: t("owner.robots.editTitle", { name }),
      yes: t("owner.save"),
      fields: [
        field("er-url", "owner.robots.address", url),
        field("er-home", "owner.robots.home", home),
        field("er-drive", "owner.robots.drive", drive),
        field("er-ros", "owner.robots.ros", ros),
        field("er-trays", "owner.robots.trays", trays),
        el("p", { class: "muted rest-hint", text: t(onTrip ? "owner.robots.editOnTrip" : "owner.robots.editNote") }),
      ],
      submit: async () => {
        const msg = { clientmsg: "site", action: "edit_robot", robot: name };
        const newUrl = url.value.trim();
        if (newUrl !== r.url) msg.url = newUrl;
        if ((home.value || null) !== (r.home || null)) msg.home = home.value || null;
        if (drive.value !== r.kinematics) msg.kinematics = drive.value;
        if (ros.value !== rosOf(r)) {
          const link = { ...(r.link || {}) };
          if (ros.value === "2") link.ros = "2";
          else delete link.ros;
          msg.link = link;
        }
        const newTrays = trays.value === "" ? null : Number(trays.value);
        if (newTrays !== (r.trays ?? null)) msg.trays = newTrays;
        if (Object.keys(msg).length === 3) return true; // nothing changed
        const reply = await this.conn.request(msg);
        toast(t("owner.robots.saved", { name: reply.robot.name }));
        return true;
      },
    });
  }

  async _removeRobot(name, button) {
    const yes = await confirmDialog(t("owner.robots.removeQuestion", { name }), {
      detail: t("owner.robots.removeDetail"),
      yes: t("owner.remove"),
      no: t("owner.cancel"),
    });
    if (!yes) return;
    const reply = await act(button, () => this.conn.request({ clientmsg: "site", action: "remove_robot", robot: name }));
    if (reply) toast(t("owner.robots.removed", { name }));
  }

  // -- tables and places ----------------------------------------------------------------------

  _placeRow(w) {
    return el(
      "li",
      { "data-waypoint": w.name, class: "rest-place" },
      el("span", { class: "rest-name", text: w.name }),
      el("span", { class: "rest-kind", text: t(`wp.kind.${w.kind}`) }),
      el("span", { class: "muted rest-pos", text: t("owner.places.position", { x: fixed(w.x), y: fixed(w.y), yaw: degrees(w.yaw) }) }),
      el(
        "div",
        { class: "row-actions" },
        el("button", {
          class: "secondary",
          "data-needs-online": true,
          "aria-label": t("owner.places.renameFor", { name: w.name }),
          text: t("owner.places.rename"),
          onclick: () => this._rename(w.name),
        }),
        el("button", {
          class: "secondary",
          "data-needs-online": true,
          "aria-label": t("owner.places.moveFor", { name: w.name }),
          text: t("owner.places.move"),
          onclick: () => this._move(w.name),
        }),
        el("button", {
          class: "danger",
          "data-needs-online": true,
          "aria-label": t("owner.places.removeFor", { name: w.name }),
          text: t("owner.remove"),
          onclick: (e) => this._removePlace(w.name, e.currentTarget),
        }),
      ),
    );
  }

  async _rename(name) {
    const input = el("input", { id: "rw-name", type: "text", maxlength: 64, required: true, autocomplete: "off", value: name });
    await formDialog({
      title: t("owner.places.renameTitle", { name }),
      yes: t("owner.places.rename"),
      fields: [field("rw-name", "owner.places.newName", input), el("p", { class: "muted rest-hint", text: t("owner.places.renameNote") })],
      submit: async () => {
        const next = input.value.trim();
        if (!next || next === name) return true;
        const reply = await this.conn.request({ clientmsg: "site", action: "rename_waypoint", waypoint: name, name: next });
        toast(t("owner.places.renamed", { old: name, name: reply.waypoint.name }));
        return true;
      },
    });
  }

  async _move(name) {
    const w = this.live.waypoints.get(name);
    if (!w) return;
    const num = (id, value, step) => el("input", { id, type: "number", step, required: true, inputmode: "decimal", value });
    const x = num("mw-x", fixed(w.x), "0.01");
    const y = num("mw-y", fixed(w.y), "0.01");
    const yaw = el("input", { id: "mw-yaw", type: "number", step: 1, min: -180, max: 360, required: true, inputmode: "numeric", value: degrees(w.yaw) });
    await formDialog({
      title: t("owner.places.moveTitle", { name }),
      yes: t("owner.places.move"),
      fields: [
        field("mw-x", "owner.places.x", x),
        field("mw-y", "owner.places.y", y),
        field("mw-yaw", "owner.places.yaw", yaw),
        el("p", { class: "muted rest-hint", text: t("owner.places.moveNote") }),
      ],
      submit: async () => {
        const msg = {
          clientmsg: "create",
          type: "waypoint",
          name,
          x: Number(x.value),
          y: Number(y.value),
          yaw: radians(yaw.value),
          kind: w.kind,
          replace: true,
        };
        await this.conn.request(msg);
        toast(t("owner.places.moved", { name, x: fixed(msg.x), y: fixed(msg.y) }));
        return true;
      },
    });
  }

  async _removePlace(name, button) {
    const reply = await act(button, () => this.conn.request({ clientmsg: "site", action: "dependents", waypoint: name }));
    if (!reply) return;
    const d = reply.dependents;
    const lines = [];
    if (d.homes.length) lines.push(t("owner.deps.homes", { robots: d.homes.join(", "), count: d.homes.length }));
    if (d.orders.length) lines.push(t("owner.deps.orders", { count: d.orders.length }));
    if (d.trips.length) lines.push(t("owner.deps.trips", { count: d.trips.length }));
    if (d.tokens.length) lines.push(t("owner.deps.tokens", { count: d.tokens.length }));
    if (d.blocked) lines.push(t("owner.deps.blocked"));
    const held = d.homes.length || d.orders.length || d.trips.length;
    const titleId = `dlg-${Math.random().toString(36).slice(2)}`;
    const list = lines.length
      ? el("ul", { class: "rest-deps", "data-testid": "dependents" }, ...lines.map((line) => el("li", { text: line })))
      : el("p", { "data-testid": "dependents", text: t("owner.deps.none") });
    const why = held ? el("p", { class: "rest-error", text: t("owner.deps.refused", { name }) }) : null;
    const failed = el("p", { class: "rest-error", role: "alert" });
    const closeBtn = el("button", { type: "button", class: "secondary", text: t(held ? "owner.close" : "owner.cancel") });
    const removeBtn = held
      ? null
      : el("button", { type: "button", class: "danger", "data-needs-online": true, text: t("owner.places.removeYes", { name }) });
    const dialog = el(
      "dialog",
      { class: "confirm rest-dialog", "aria-labelledby": titleId },
      el("h2", { id: titleId, text: t("owner.places.removeQuestion", { name }) }),
      el("p", { text: t("owner.deps.intro") }),
      list,
      why,
      failed,
      el("div", { class: "dialog-buttons" }, closeBtn, removeBtn),
    );
    const finish = () => {
      dialog.close();
      dialog.remove();
    };
    closeBtn.addEventListener("click", finish);
    dialog.addEventListener("cancel", (e) => {
      e.preventDefault();
      finish();
    });
    if (removeBtn) {
      removeBtn.addEventListener("click", async () => {
        removeBtn.disabled = true;
        try {
          await this.conn.request({ clientmsg: "site", action: "remove_waypoint", waypoint: name });
          finish();
          toast(t("owner.places.removed", { name }));
        } catch (err) {
          // Something came to depend on it meanwhile: the server says what.
          failed.textContent = describeError(err);
          removeBtn.disabled = false;
        }
      });
    }
    document.body.append(dialog);
    dialog.showModal();
    closeBtn.focus();
  }

  // -- settings -------------------------------------------------------------------------------

  _gotSettings(settings, { force = false } = {}) {
    if (!settings) return;
    const traysChanged = !this.settings || this.settings.trays !== settings.trays;
    this.settings = settings;
    if (traysChanged) {
      this.robotRows.invalidate();
      this.render();
    }
    if (this.dirty && !force) return;
    this.dirty = false;
    const forever = settings.table_timeout === null || settings.table_timeout === undefined;
    this.forever.checked = forever;
    this.timeout.value = forever ? "" : String(Math.round(settings.table_timeout));
    this.trays.value = String(settings.trays);
    this.autoDepart.checked = Boolean(settings.auto_depart);
    for (const l of LANGS) this.langBoxes[l].checked = settings.languages.includes(l);
    this._fillLanguage(settings.language);
    this._syncSettingsForm();
  }

  /** The default language picks among the languages ticked; "for ever" needs no seconds. */
  _syncSettingsForm() {
    this.timeout.disabled = this.forever.checked;
    this.timeout.required = !this.forever.checked;
    const ticked = LANGS.filter((l) => this.langBoxes[l].checked);
    // At least one language: the last one ticked cannot be unticked.
    for (const l of LANGS) this.langBoxes[l].disabled = ticked.length === 1 && this.langBoxes[l].checked;
    this._fillLanguage();
  }

  _fillLanguage(want = null) {
    const keep = want || this.language.value;
    const ticked = LANGS.filter((l) => this.langBoxes[l].checked);
    const shown = ticked.length ? ticked : LANGS;
    this.language.replaceChildren(...shown.map((l) => el("option", { value: l, text: t(`lang.${l}`) })));
    this.language.value = shown.includes(keep) ? keep : shown[0];
  }

  async _saveSettings() {
    const languages = LANGS.filter((l) => this.langBoxes[l].checked);
    const msg = {
      clientmsg: "site",
      action: "set_settings",
      table_timeout: this.forever.checked ? null : Number(this.timeout.value),
      trays: Number(this.trays.value),
      auto_depart: this.autoDepart.checked,
      languages,
      language: this.language.value,
    };
    const reply = await act(this.saveBtn, () => this.conn.request(msg));
    if (!reply) return;
    this.dirty = false;
    this._gotSettings(reply.settings, { force: true });
    toast(t("owner.settings.saved"));
  }
}
