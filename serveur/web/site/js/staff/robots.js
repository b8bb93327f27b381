// The robots list: status, battery, current trip, and the instructions the robot's status
// allows (status.js). A refusal from the server (the status changed meanwhile) is shown.
// A robot waiting for a zone (waiting_for) says which, and which robot is in it (the leases).
// A trip is worded by its kind and stop (trips.js: plates, a cruise, a birthday); a free robot
// may go to charge (with a dock) or cruise (cruise.js), a charging one back to work.

import { act, confirmDialog, el, formatClock, KeyedList, refocus } from "../ui.js";
import { allowed, statusColour } from "../status.js";
import { onLangChange, t } from "../i18n.js";
import { goButton, trayList, traySignature } from "./dishes.js";
import { technicalNote, troubleWords } from "./trouble.js";
import { cruising, nextKey, statusWords, tripWords } from "./trips.js";
import { endCruise, pickCruise } from "./cruise.js";

// [action, label key, request]. `ready` takes a robot out of Manual (staff are done driving it)
// or out of Auto (it stops taking trips): its words depend on which (readyKey).
// The robot's next action first (Food collected, Continue...); Take control, possible from
// nearly every status in one step, last.
const ACTIONS = [
  ["auto", "robots.auto", (r) => ({ clientmsg: "control", robot: r, action: "auto" })],
  ["work", "robots.work", (r) => ({ clientmsg: "work", robot: r })],
  ["next", "robots.collected", (r, at) => ({ clientmsg: "next", robot: r, ...at })],
  ["continue", "robots.continue", (r, at) => ({ clientmsg: "continue", robot: r, ...at })],
  ["ready", "robots.pause", (r) => ({ clientmsg: "ready", robot: r })],
  ["charge", "robots.charge", (r) => ({ clientmsg: "charge", robot: r })],
  ["stop", "robots.stop", (r, at) => ({ clientmsg: "stop", robot: r, ...at })],
  ["skip", "robots.skip", (r, at) => ({ clientmsg: "skip", robot: r, ...at })],
  ["cancel", "robots.cancel", (r, at) => ({ clientmsg: "cancel", robot: r, ...at })],
  ["manual", "robots.manual", (r) => ({ clientmsg: "control", robot: r, action: "manual" })],
];

/** The `ready` button's words: "Done driving" under staff control, else "Pause deliveries". */
function readyKey(robot) {
  return robot.status === "Manual" ? "robots.doneDriving" : "robots.pause";
}

export class RobotsPanel {
  constructor(list, conn, live, selection) {
    this.list = list;
    this.conn = conn;
    this.live = live;
    this.selection = selection;
    // Rebuild a row only when what it shows changed, so a button is not replaced under a finger;
    // a rebuilt row keeps the keyboard's place (ui.js KeyedList), also while a button pressed is
    // disabled for its request (the row the robot's new status redraws meanwhile).
    this.rows = new KeyedList(list, {
      key: (robot) => robot.name,
      signature: (robot) => {
        const loading = robot.status === "Loading" ? traySignature(this.live, robot.current_task) : "";
        return [
          robot.status, robot.mode, battery(robot), this._trip(robot), this.selection.name === robot.name, robot.last_error,
          loading, robot.status_since, this.live.destination(robot.name), this._waiting(robot), Boolean(robot.lost),
          statusWords(this.live, robot), nextKey(this.live, robot), robot.dock ?? null,
        ];
      },
      build: (robot) => this._row(robot),
      lostFocus: (robot) => (this._acting && this._acting.name === robot.name ? this._acting.action : null),
    });
    live.addEventListener("change", (e) => {
      if (["robots", "tasks", "waypoints", "orders", "leases"].includes(e.detail.topic)) this.render();
    });
    // Time at the table ticks: only that text changes, once a second.
    setInterval(() => this._tick(), 1000);
    selection.onChange(() => this.render());
    onLangChange(() => {
      this.rows.invalidate(); // same data, new words
      this.render();
    });
  }

  render() {
    const names = [...this.live.robots.keys()].sort();
    this.rows.update(names.map((name) => this.live.robots.get(name)));
  }

  _row(robot) {
    const selected = this.selection.name === robot.name;
    return el(
      "li",
      { class: selected ? "robot selected" : "robot", "data-status": robot.status },
      ...this._content(robot, this._trip(robot), selected).filter(Boolean),
    );
  }

  _trip(robot) {
    return tripWords(this.live, robot);
  }

  _content(robot, trip, selected) {
    const name = robot.name;
    const onTrip = robot.current_task !== null && robot.current_task !== undefined;
    const cruise = cruising(this.live, robot);
    // Skip needs a table to leave: only on a trip. Charging needs a charger. A cruise ends
    // with "Back to deliveries", not by skipping or cancelling a place.
    const offered = ([action]) =>
      allowed(robot.status, action) &&
      (action !== "skip" || onTrip) &&
      (action !== "charge" || Boolean(robot.dock)) &&
      !(cruise && (action === "skip" || action === "cancel"));
    const buttons = ACTIONS.filter(offered).map(([action, actionKey, make]) => {
      const key = action === "ready" ? readyKey(robot) : action === "next" ? nextKey(this.live, robot) : actionKey;
      return el("button", {
        class: action === "stop" || action === "cancel" ? "danger" : action === "skip" ? "secondary" : "",
        "data-needs-online": true,
        "data-focus-key": action,
        "aria-label": t("robots.actionFor", { action: t(key), name }),
        // The trip and stop shown now: the server refuses the command if the robot moved on.
        onclick: (e) => this._do(e.currentTarget, action, name, make(name, this.live.target(name))),
        text: t(key),
      });
    });
    // "Cruise…", "Back to deliveries": before "Take control", which stays last.
    const last = buttons.length && buttons[buttons.length - 1].dataset.focusKey === "manual" ? buttons.pop() : null;
    buttons.push(...this._modeButtons(robot, cruise));
    if (last) buttons.push(last);
    return [
      el(
        "button",
        {
          class: "robot-name",
          "data-focus-key": "select",
          "aria-pressed": String(selected),
          "aria-label": t("robots.select", { name }),
          onclick: () => this.selection.set(name),
        },
        name,
      ),
      el(
        "span",
        { class: "status-badge", "data-status": robot.status },
        el("span", { class: "dot", "aria-hidden": "true", style: { background: statusColour(robot.status) } }),
        statusWords(this.live, robot),
      ),
      el("span", { class: "battery" }, t("robots.battery", { value: battery(robot) })),
      el("span", { class: "trip" }, trip),
      this._trouble(robot),
      robot.lost ? el("span", { class: "lost", "data-testid": "lost", role: "status" }, t("robots.lost")) : null,
      robot.waiting_for && robot.waiting_for.length
        ? el("span", { class: "waiting-for", "data-testid": "waiting-for" }, this._waiting(robot))
        : null,
      this._atTable(robot),
      robot.status === "Loading" ? this._loading(robot) : null,
      el("div", { class: "actions", role: "group", "aria-label": t("robots.actions", { name }) }, buttons),
    ];
  }

  /** "Cruise…" for a free robot, "Back to deliveries" for a cruising one. */
  _modeButtons(robot, cruise) {
    const name = robot.name;
    const made = [];
    if (allowed(robot.status, "cruise")) {
      made.push(
        el("button", {
          class: "secondary",
          "data-needs-online": true,
          "data-focus-key": "cruise",
          "aria-label": t("robots.actionFor", { action: t("robots.cruise"), name }),
          text: t("robots.cruise"),
          onclick: () => pickCruise(this.conn, this.live, name),
        }),
      );
    }
    if (cruise) {
      made.push(
        el("button", {
          "data-needs-online": true,
          "data-focus-key": "deliveries",
          "aria-label": t("robots.actionFor", { action: t("robots.backToDeliveries"), name }),
          text: t("robots.backToDeliveries"),
          onclick: (e) => endCruise(this.conn, this.live, e.currentTarget, name),
        }),
      );
    }
    return made;
  }

  /** What went wrong, in words (trouble.js), with the robot's own text folded underneath. */
  _trouble(robot) {
    const words = troubleWords(robot, this.live);
    if (!words && !robot.last_error) return null;
    return el("div", { class: "last-error" }, words ? el("span", { class: "trouble" }, words) : null, technicalNote(robot.last_error));
  }

  /** The tables of `name`'s trip not served yet, "T5, T7", or "". */
  _tripTables(name) {
    const robot = this.live.robots.get(name);
    const task = robot && this.live.tasks.get(robot.current_task);
    if (!task) return "";
    return task.stops.slice(task.current_stop ?? 0).map((s) => s.table).join(", ");
  }

  /** "Waiting for aisle (held by r2)": the zones a robot waits for and who is in them, or "". */
  _waiting(robot) {
    const zones = robot.waiting_for;
    if (!zones || !zones.length) return "";
    const holders = new Set();
    for (const z of zones) {
      const lease = this.live.leases.get(z);
      for (const r of (lease && lease.holders) || []) if (r !== robot.name) holders.add(r);
    }
    const names = zones.join(", ");
    return holders.size
      ? t("robots.waitingHeld", { zones: names, robots: [...holders].sort().join(", ") })
      : t("robots.waitingQueue", { zones: names });
  }

  /** A robot waiting at a table: where, and for how long (ticks each second). */
  _atTable(robot) {
    if (robot.status !== "Delivered") return null;
    const table = this.live.destination(robot.name);
    const span = el("span", {
      class: "at-table",
      "data-since": robot.status_since,
      "data-table": table || "",
    });
    this._showAt(span);
    return span;
  }

  _showAt(span) {
    const since = Number(span.dataset.since);
    const time = formatClock(since ? this.live.clock.now() - since : 0);
    span.textContent = span.dataset.table
      ? t("robots.atTable", { table: span.dataset.table, time })
      : t("robots.atTableAny", { time });
  }

  _tick() {
    for (const span of this.list.querySelectorAll(".at-table")) this._showAt(span);
  }

  /** Loading at the pass: what goes on which tray, and the big Go. */
  _loading(robot) {
    return el(
      "div",
      { class: "loading" },
      el("span", { class: "loading-title" }, t("loading.title")),
      trayList(this.live, robot.current_task),
      goButton(this.conn, this.live, robot.name),
    );
  }

  async _do(button, action, name, msg) {
    if (action === "skip") {
      const table = this.live.destination(name);
      const yes = await confirmDialog(t("robots.skipQuestion", { table: table || "?" }), {
        yes: t("robots.skipYes"),
        no: t("robots.skipNo"),
        detail: t("robots.skipDetail"),
      });
      if (!yes) return;
    }
    if (action === "manual" && this.live.robots.get(name)?.current_task != null) {
      // One step, but a trip under way is given up: asked first.
      const tables = this._tripTables(name);
      const yes = await confirmDialog(t("robots.takeQuestion", { name }), {
        yes: t("robots.takeYes"),
        no: t("robots.takeNo"),
        detail: tables ? t("robots.takeDetail", { tables }) : t("robots.takeDetailAny"),
      });
      if (!yes) return;
    }
    if (action === "cancel") {
      const yes = await confirmDialog(t("robots.cancelQuestion", { name }), {
        yes: t("robots.cancelYes"),
        no: t("robots.cancelNo"),
        detail: t("robots.cancelDetail"),
      });
      if (!yes) return;
    }
    this._acting = { name, action };
    let reply = null;
    try {
      reply = await act(button, () => this.conn.request(msg));
    } finally {
      this._acting = null;
    }
    if (reply && action === "manual") this._showDriving(name);
    // Focus kept: on the button pressed if still there, else on the robot's row.
    if (!document.activeElement || document.activeElement === document.body) this._refocus(name, action);
  }

  /**
   * Taken control on a phone or a portrait tablet: the robot is selected, the page shows the
   * map and the pads first (staff.css, body[data-driving]), scrolled to the map's tools.
   */
  _showDriving(name) {
    if (!window.matchMedia("(max-width: 900px)").matches) return;
    if (this.selection.name !== name) this.selection.set(name);
    // The map (its tools on top) and the pads under it fill the screen.
    requestAnimationFrame(() => document.querySelector(".map-area")?.scrollIntoView({ block: "start", behavior: "instant" }));
  }

  /** Focus the row's control `key` (an action, "select"), or its first usable one (its name). */
  _refocus(name, key) {
    const row = this.rows.node(name);
    if (row) refocus(row, key);
  }
}

function battery(robot) {
  return robot.battery === null || robot.battery === undefined
    ? t("robots.batteryUnknown")
    : t("robots.batteryPercent", { percent: Math.round(robot.battery * 100) });
}
