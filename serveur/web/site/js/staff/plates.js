// "Send a robot for plates", under the robots list: staff pick the tables whose used dishes a
// robot should collect, and one `create bussing` sends it (the server picks the robot and when
// it may leave: dishes waiting at the pass go first). It brings them to the dish return, where
// staff empty it. Without a dish return place the server refuses, worded by errors.js ("Add a
// dish return place first"), and the form says so before anyone presses.

import { byName, el, newKey, toast } from "../ui.js";
import { t } from "../i18n.js";
import { formDialog } from "./forms.js";

export class PlatesButton {
  constructor(root, conn, live) {
    this.conn = conn;
    this.live = live;
    this.button = el("button", {
      type: "button",
      class: "secondary plates-send",
      "data-needs-online": true,
      "data-i18n": "plates.send",
      onclick: () => this.open(),
    });
    root.append(this.button);
  }

  async open() {
    const tables = [...this.live.waypoints.values()].filter((w) => w.kind === "table").map((w) => w.name).sort(byName);
    const hasReturn = [...this.live.waypoints.values()].some((w) => w.kind === "dish_return");
    const chosen = new Set();
    const picks = tables.map((table) =>
      el("button", {
        type: "button",
        class: "table-btn",
        "aria-pressed": "false",
        "aria-label": t("order.tableNamed", { table }),
        text: table,
        onclick: (e) => {
          if (chosen.has(table)) chosen.delete(table);
          else chosen.add(table);
          e.currentTarget.setAttribute("aria-pressed", String(chosen.has(table)));
        },
      }),
    );
    // No idempotency key: the server refuses a bussing trip's key (its store's key table
    // knows only orders and tasks), so this request is not resent after a dropped connection.
    await formDialog({
      title: t("plates.title"),
      yes: t("plates.go"),
      fields: [
        el("p", { class: "muted rest-hint", text: t("plates.note") }),
        hasReturn ? null : el("p", { class: "rest-error", "data-testid": "no-dish-return", text: t("plates.noReturn") }),
        tables.length
          ? el("div", { class: "table-grid", role: "group", "aria-label": t("plates.tables") }, ...picks)
          : el("p", { class: "muted", text: t("order.noTables") }),
      ].filter(Boolean),
      submit: async () => {
        const list = tables.filter((table) => chosen.has(table));
        if (!list.length) {
          const err = new Error(t("plates.pickFirst"));
          err.local = true;
          throw err;
        }
        // A key: a reply lost on the Wi-Fi and the request resent is still one trip.
        this.key = this.key || newKey("bussing");
        const reply = await this.conn.request({ clientmsg: "create", type: "bussing", tables: list, key: this.key });
        this.key = null;
        toast(reply.task && reply.task.robot ? t("plates.sentRobot", { robot: reply.task.robot, tables: list.join(", ") }) : t("plates.sent", { tables: list.join(", ") }));
        return true;
      },
    });
  }
}
