// Waypoints: save the selected robot's current pose under a name (drive it to the table, then
// save), and the Go-To list (click a waypoint to send the selected robot there).

import { act, byName, confirmDialog, el, KeyedList, toast } from "../ui.js";
import { allowed } from "../status.js";
import { onLangChange, t } from "../i18n.js";
import { kindName, PLACE_KINDS } from "./kinds.js";

export class WaypointsPanel {
  constructor(root, conn, live, selection) {
    this.conn = conn;
    this.live = live;
    this.selection = selection;
    this.name = el("input", { id: "wp-name", type: "text", maxlength: 64, required: true, autocomplete: "off" });
    this.kind = el("select", { id: "wp-kind" }, PLACE_KINDS.map((k) => el("option", { value: k, text: kindName(k) })));
    this.saveBtn = el("button", { type: "submit", "data-needs-online": true, "data-i18n": "wp.save" });
    this.list = el("ul", { class: "goto-list", "data-i18n-aria-label": "wp.gotoList" });
    const form = el(
      "form",
      { class: "wp-form", "data-i18n-aria-label": "wp.form" },
      el("label", { for: "wp-name", "data-i18n": "wp.name" }),
      this.name,
      el("label", { for: "wp-kind", "data-i18n": "wp.kind" }),
      this.kind,
      this.saveBtn,
    );
    form.addEventListener("submit", (e) => {
      e.preventDefault();
      this._save();
    });
    root.append(
      el(
        "section",
        { class: "waypoints", "aria-labelledby": "wp-title" },
        el("h3", { id: "wp-title", "data-i18n": "wp.title" }),
        form,
        el("h4", { "data-i18n": "wp.goto" }),
        this.list,
      ),
    );
    // One Go-To button per waypoint, drawn again only when whether it can go (or where to) changed.
    this.rows = new KeyedList(this.list, {
      key: (n) => n,
      signature: () => [this._canGo(), this.selection.name],
      build: (n) => this._row(n),
    });
    live.addEventListener("change", (e) => {
      if (e.detail.topic === "waypoints" || e.detail.topic === "robots") this.render();
    });
    selection.onChange(() => this.render());
    onLangChange(() => {
      for (const option of this.kind.options) option.textContent = kindName(option.value);
      this.rows.invalidate(); // same list, new words
      this.render();
    });
    this.render();
  }

  _canGo() {
    const robot = this.live.robots.get(this.selection.name);
    return Boolean(robot && allowed(robot.status, "goto"));
  }

  render() {
    const robot = this.live.robots.get(this.selection.name);
    this.saveBtn.disabled = !(robot && allowed(robot.status, "save_waypoint"));
    this.rows.update([...this.live.waypoints.keys()].sort(byName));
  }

  _row(n) {
    const canGo = this._canGo();
    return el(
      "li",
      {},
      el("button", {
        disabled: !canGo,
        "data-needs-online": true,
        "aria-label": t("wp.gotoNamed", { name: n }),
        title: canGo ? t("wp.send", { robot: this.selection.name, name: n }) : t("wp.needControl"),
        onclick: (e) => this._goto(e.currentTarget, n),
        text: n,
      }),
    );
  }

  async _save() {
    const robot = this.selection.name;
    const name = this.name.value.trim();
    if (!robot || !name) return;
    const msg = { clientmsg: "create", type: "waypoint", name, robot, kind: this.kind.value };
    if (this.live.waypoints.has(name)) {
      const yes = await confirmDialog(t("wp.replaceQuestion", { name }), {
        yes: t("wp.replaceYes"),
        no: t("wp.replaceNo"),
        detail: t("wp.replaceDetail", { name, robot }),
      });
      if (!yes) return;
      msg.replace = true;
    }
    const reply = await act(this.saveBtn, () => this.conn.request(msg));
    this.render();
    if (reply) {
      const w = reply.waypoint;
      toast(t("wp.saved", { name: w.name }));
      this.name.value = "";
    }
  }

  async _goto(button, waypoint) {
    const robot = this.selection.name;
    const reply = await act(button, () =>
      this.conn.request({ clientmsg: "control", robot, action: "goto", waypoint }),
    );
    if (reply) toast(t("wp.going", { robot, name: waypoint }));
  }
}
