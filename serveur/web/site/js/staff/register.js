// Register a robot (owners only): its name, its rosbridge address, where it parks and how it
// drives. The server connects to it at once; the robot then shows in the list, Offline until
// the server reaches it, Ready after. Staff do not see the form (the server would refuse).

import { act, byName, el, KeyedList, toast } from "../ui.js";
import { t } from "../i18n.js";

const KINEMATICS = [
  ["omni", "register.omni"],
  ["diff", "register.diff"],
];

export class RegisterRobot {
  constructor(root, conn, live) {
    this.conn = conn;
    this.live = live;
    this.name = el("input", {
      id: "rr-name", type: "text", maxlength: 64, required: true, autocomplete: "off",
      "data-i18n-placeholder": "register.namePlaceholder",
    });
    this.url = el("input", {
      id: "rr-url", type: "text", required: true, autocomplete: "off", spellcheck: "false",
      "data-i18n-placeholder": "register.urlPlaceholder", pattern: "wss?://.+",
      "data-i18n-title": "register.urlHint",
    });
    // The free homes, one option each, then "no home" (last, kept): an option stays while its
    // home is free, so the choice made is not undone by an update.
    this.home = el("select", { id: "rr-home" }, el("option", { value: "", "data-i18n": "register.noHome" }));
    this.homes = new KeyedList(this.home, { key: (h) => h, build: (h) => el("option", { value: h }, h) });
    this.noHomeChosen = false; // "no home" picked by hand: kept when homes come and go
    this.home.addEventListener("change", () => {
      this.noHomeChosen = this.home.value === "";
    });
    this.kinematics = el(
      "select",
      { id: "rr-kinematics" },
      KINEMATICS.map(([v, key]) => el("option", { value: v, "data-i18n": key })),
    );
    // ROS1 robots run move_base; ROS 2 robots Nav2 over rosbridge 2.x (docs/robots.md).
    this.ros = el(
      "select",
      { id: "rr-ros" },
      el("option", { value: "1", "data-i18n": "register.ros1" }),
      el("option", { value: "2", "data-i18n": "register.ros2" }),
    );
    this.submit = el("button", { type: "submit", "data-needs-online": true, "data-i18n": "register.submit" });
    const form = el(
      "form",
      { class: "wp-form", "data-i18n-aria-label": "register.title" },
      el("label", { for: "rr-name", "data-i18n": "register.name" }),
      this.name,
      el("label", { for: "rr-url", "data-i18n": "register.url" }),
      this.url,
      el("label", { for: "rr-home", "data-i18n": "register.home" }),
      this.home,
      el("label", { for: "rr-kinematics", "data-i18n": "register.drive" }),
      this.kinematics,
      el("label", { for: "rr-ros", "data-i18n": "register.ros" }),
      this.ros,
      this.submit,
    );
    form.addEventListener("submit", (e) => {
      e.preventDefault();
      if (form.reportValidity()) this._register();
    });
    this.section = el(
      "details",
      { class: "register", hidden: true },
      el("summary", { "data-i18n": "register.title" }),
      form,
    );
    root.append(this.section);
    conn.addEventListener("session", (e) => {
      this.section.hidden = e.detail.session.role !== "owner";
    });
    live.addEventListener("change", (e) => {
      if (e.detail.topic === "waypoints" || e.detail.topic === "robots") this.renderHomes();
    });
    this.renderHomes();
  }

  /** Home spots no robot has taken yet, the first of them chosen. */
  renderHomes() {
    const taken = new Set([...this.live.robots.values()].map((r) => r.home));
    const homes = [...this.live.waypoints.values()]
      .filter((w) => w.kind === "home" && !taken.has(w.name))
      .map((w) => w.name)
      .sort(byName);
    const keep = this.home.value;
    this.homes.update(homes);
    // The first free home is chosen, unless a free one (or "no home") was picked by hand.
    if (!homes.includes(keep) && !(keep === "" && this.noHomeChosen)) this.home.selectedIndex = 0;
  }

  async _register() {
    const name = this.name.value.trim();
    const url = this.url.value.trim();
    const msg = { clientmsg: "create", type: "robot", name, url, kinematics: this.kinematics.value };
    if (this.home.value) msg.home = this.home.value;
    if (this.ros.value === "2") msg.link = { ros: "2" };
    const reply = await act(this.submit, () => this.conn.request(msg));
    if (!reply) return;
    toast(t("register.done", { name: reply.robot.name }));
    this.name.value = "";
    this.url.value = "";
  }
}
