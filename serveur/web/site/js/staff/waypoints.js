// Waypoints: save the selected robot's current pose under a name (drive it to the table, then
// save), and the Go-To list (click a waypoint to send the selected robot there).

import { act, byName, confirmDialog, el, toast } from "../ui.js";
import { allowed } from "../status.js";

const KINDS = ["table", "home", "pass", "other"];

export class WaypointsPanel {
  constructor(root, conn, live, selection) {
    this.conn = conn;
    this.live = live;
    this.selection = selection;
    this.name = el("input", { id: "wp-name", type: "text", maxlength: 64, required: true, autocomplete: "off" });
    this.kind = el("select", { id: "wp-kind" }, KINDS.map((k) => el("option", { value: k }, k)));
    this.saveBtn = el("button", { type: "submit", text: "Save waypoint" });
    this.list = el("ul", { class: "goto-list", "aria-label": "Go to a waypoint" });
    const form = el(
      "form",
      { class: "wp-form", "aria-label": "Save the robot's pose as a waypoint" },
      el("label", { for: "wp-name" }, "Name"),
      this.name,
      el("label", { for: "wp-kind" }, "Kind"),
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
        el("h3", { id: "wp-title" }, "Waypoints"),
        form,
        el("h4", {}, "Go to"),
        this.list,
      ),
    );
    live.addEventListener("change", (e) => {
      if (e.detail.topic === "waypoints" || e.detail.topic === "robots") this.render();
    });
    selection.onChange(() => this.render());
    this.render();
  }

  render() {
    const robot = this.live.robots.get(this.selection.name);
    const canSave = Boolean(robot && allowed(robot.status, "save_waypoint"));
    const canGo = Boolean(robot && allowed(robot.status, "goto"));
    this.saveBtn.disabled = !canSave;
    const names = [...this.live.waypoints.keys()].sort(byName);
    const signature = JSON.stringify([names, canGo, this.selection.name]);
    if (signature === this._signature) return;
    this._signature = signature;
    this.list.replaceChildren(
      ...names.map((n) =>
        el(
          "li",
          {},
          el("button", {
            disabled: !canGo,
            "aria-label": `Go to ${n}`,
            title: canGo ? `Send ${this.selection.name} to ${n}` : "Take control of the robot first",
            onclick: (e) => this._goto(e.currentTarget, n),
            text: n,
          }),
        ),
      ),
    );
  }

  async _save() {
    const robot = this.selection.name;
    const name = this.name.value.trim();
    if (!robot || !name) return;
    const msg = { clientmsg: "create", type: "waypoint", name, robot, kind: this.kind.value };
    if (this.live.waypoints.has(name)) {
      const yes = await confirmDialog(`Replace waypoint ${name}?`, {
        yes: "Yes, replace it",
        no: "No",
        detail: `A waypoint named ${name} exists; it will move to ${robot}'s pose.`,
      });
      if (!yes) return;
      msg.replace = true;
    }
    const reply = await act(this.saveBtn, () => this.conn.request(msg));
    this.render();
    if (reply) {
      const w = reply.waypoint;
      toast(`Saved ${w.name} at (${w.x.toFixed(2)}, ${w.y.toFixed(2)})`);
      this.name.value = "";
    }
  }

  async _goto(button, waypoint) {
    const robot = this.selection.name;
    const reply = await act(button, () =>
      this.conn.request({ clientmsg: "control", robot, action: "goto", waypoint }),
    );
    if (reply) toast(`${robot}: going to ${waypoint}`);
  }
}
