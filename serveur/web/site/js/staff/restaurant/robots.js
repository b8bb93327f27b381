// The Restaurant tab's robots: each robot's address, ROS, drive, home, charger (its dock), trays,
// status and why the server cannot reach it; edit one (`site edit_robot`) or remove it (`site
// remove_robot`). Its
// own module so that the panel (restaurant.js) only lays the sections out.

import { byName, el, toast } from "../../ui.js";
import { t } from "../../i18n.js";
import { field, formDialog } from "../forms.js";
import { confirmRemove, listSection, rowButton } from "./form.js";
import { MAX_TRAYS } from "./settings.js";
import { statusWords } from "../trips.js";

const KINEMATICS = { omni: "owner.drive.omni", diff: "owner.drive.diff" };

function rosOf(robot) {
  return (robot.link && robot.link.ros) === "2" ? "2" : "1";
}

export class RobotsSection {
  /** `siteTrays()`: the site's trays per robot (null until the settings are read). */
  constructor(conn, live, siteTrays) {
    this.conn = conn;
    this.live = live;
    this.siteTrays = siteTrays;
    ({ rows: this.rows, section: this.section } = listSection({
      titleId: "rest-robots-title",
      title: "owner.robots.title",
      note: "owner.robots.note",
      none: "owner.robots.none",
      signature: (r) => [r.url, r.link, r.kinematics, r.home, r.dock, r.trays, statusWords(live, r), r.link_error, r.current_task, this.siteTrays()],
      build: (r) => this._row(r),
    }));
  }

  render() {
    this.rows.update([...this.live.robots.values()].sort((a, b) => byName(a.name, b.name)));
  }

  _row(r) {
    const trays = r.trays === null || r.trays === undefined ? t("owner.robots.traysSite", { count: this.siteTrays() ?? "?" }) : String(r.trays);
    const detail = (key, value) => el("div", {}, el("dt", { text: t(key) }), el("dd", { text: value }));
    return el(
      "li",
      { "data-robot": r.name, class: "rest-robot" },
      el(
        "div",
        { class: "rest-head" },
        el("span", { class: "rest-name", text: r.name }),
        el("span", { class: "rest-status", text: statusWords(this.live, r) }),
      ),
      el(
        "dl",
        { class: "rest-details" },
        detail("owner.robots.address", r.url),
        detail("owner.robots.ros", t("owner.ros.n", { n: rosOf(r) })),
        detail("owner.robots.drive", t(KINEMATICS[r.kinematics] || "owner.drive.omni")),
        detail("owner.robots.home", r.home || t("owner.robots.noHome")),
        detail("owner.robots.dock", r.dock || t("owner.robots.noDock")),
        detail("owner.robots.trays", trays),
      ),
      r.link_error ? el("p", { class: "rest-error", "data-testid": "link-error", text: t("owner.robots.linkError", { error: r.link_error }) }) : null,
      r.current_task !== null && r.current_task !== undefined
        ? el("p", { class: "muted", text: t("owner.robots.onTrip", { trip: r.current_task }) })
        : null,
      el(
        "div",
        { class: "row-actions" },
        rowButton(t("owner.edit"), t("owner.robots.editFor", { name: r.name }), () => this._edit(r.name)),
        rowButton(t("owner.remove"), t("owner.robots.removeFor", { name: r.name }), (e) => this._remove(r.name, e.currentTarget), { danger: true }),
      ),
    );
  }

  async _edit(name) {
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
    // Its charger: a place of kind dock (the robot goes there to charge).
    const docks = [...this.live.waypoints.values()].filter((w) => w.kind === "dock").sort((a, b) => byName(a.name, b.name));
    const dock = el(
      "select",
      { id: "er-dock" },
      el("option", { value: "", text: t("owner.robots.noDock") }),
      ...docks.map((w) => el("option", { value: w.name, text: w.name })),
    );
    dock.value = docks.some((w) => w.name === r.dock) ? r.dock : "";
    const drive = el("select", { id: "er-drive" }, ...Object.entries(KINEMATICS).map(([v, key]) => el("option", { value: v, text: t(key) })));
    drive.value = r.kinematics;
    const ros = el("select", { id: "er-ros" }, ...["1", "2"].map((n) => el("option", { value: n, text: t("owner.ros.n", { n }) })));
    ros.value = rosOf(r);
    const trays = el(
      "select",
      { id: "er-trays" },
      el("option", { value: "", text: t("owner.robots.traysSite", { count: this.siteTrays() ?? "?" }) }),
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
        field("er-dock", "owner.robots.dock", dock, docks.length ? null : el("p", { class: "muted rest-hint", text: t("owner.robots.noDocks") })),
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
        if ((dock.value || null) !== (r.dock || null)) msg.dock = dock.value || null;
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

  _remove(name, button) {
    return confirmRemove(button, {
      question: t("owner.robots.removeQuestion", { name }),
      detail: t("owner.robots.removeDetail"),
      run: () => this.conn.request({ clientmsg: "site", action: "remove_robot", robot: name }),
      done: t("owner.robots.removed", { name }),
    });
  }
}
