// The setup page's last step: one test trip, then the console. Offered once there is a pass,
// a table and a robot with a home (places.js). The owner picks a robot and a table; the page
// wakes the robot for deliveries (`ready` from manual control, then `control` `auto`), makes one
// dish ready at the pass for that table (`create order`) and the cart of it (`create task`),
// both with a key so a resend makes nothing twice. Then it follows the trip on the live topics
// in plain words: the robot loading at the pass (Go, here or on the robot's screen), on its way,
// at the table (Food collected, which the guest presses on the robot's screen; here too), home
// again. Left at the table, the robot goes on by itself after the site's time at a table and the
// dish counts as returned: the page says so and takes the test dish off the pass (`dish` `void`).
// The trip is remembered on this tablet, so the page opened again follows it still.

import { describeError, el, formatDuration, KeyedList, newKey } from "../ui.js";
import { onLangChange, statusName, t } from "../i18n.js";
import { keep, kept } from "../keep.js";
import { placesState } from "./places.js";
import { say, show } from "./steps.js";

const KEY = "serveur.setup.trip";
// From these a robot can be woken for deliveries; any other is busy (or cannot move).
const WAKE = new Set(["Ready", "Manual", "Awaiting", "Transit"]);

/** A time at a table in words: whole minutes as such, else minutes and seconds. */
function limitWords(seconds) {
  return seconds % 60 === 0 ? t("setup.trip.minutes", { count: seconds / 60 }) : formatDuration(seconds);
}

// Storage disabled: the trip is followed until the page is left.
const load = () => kept(KEY);
const store = (trip) => keep(KEY, trip || null);

export class TripStep {
  constructor(conn, live) {
    this.conn = conn;
    this.live = live;
    this.trip = load(); // {order, task, robot, table, end} of the test trip, if one was sent
    this.form = document.getElementById("trip-form");
    this.robotSelect = document.getElementById("trip-robot");
    this.tableSelect = document.getElementById("trip-table");
    this.sendBtn = document.getElementById("trip-send");
    this.progress = document.getElementById("trip-progress");
    this.how = document.getElementById("trip-how");
    this.goBtn = document.getElementById("trip-go");
    this.collectedBtn = document.getElementById("trip-collected");
    this.robots = new KeyedList(this.robotSelect, {
      key: (name) => name,
      build: (name) => el("option", { value: name, text: name }),
    });
    this.tables = new KeyedList(this.tableSelect, {
      key: (name) => name,
      build: (name) => el("option", { value: name, text: name }),
    });
    this.form.addEventListener("submit", (e) => {
      e.preventDefault();
      this.send();
    });
    this.tablePicked = false; // the owner chose the table: it is kept
    this.robotSelect.addEventListener("change", () => this.tablePicked || this.pickNearestTable());
    this.tableSelect.addEventListener("change", () => (this.tablePicked = true));
    this.goBtn.addEventListener("click", () => this.press(this.goBtn, "go"));
    this.collectedBtn.addEventListener("click", () => this.press(this.collectedBtn, "next"));
    document.getElementById("trip-back").addEventListener("click", () => show("places"));
    live.addEventListener("change", (e) => {
      const topic = e.detail.topic;
      // The dishes' snapshot (a page opened again) without the test dish: it ended meanwhile
      // (delivered and voided dishes are not in it).
      if (topic === "orders" && e.detail.record === null) this.gone();
      if (["robots", "waypoints", "orders", "tasks", "settings"].includes(topic)) this.render();
    });
    onLangChange(() => this.render());
    this.render();
  }

  /** The robots that can take a trip (a home to come back to) and the tables. */
  render() {
    const state = placesState(this.live);
    const robots = state.homes.filter((h) => h.home).map((h) => h.robot);
    const chosen = this.robotSelect.value;
    this.robots.update(robots);
    if (!robots.includes(chosen)) this.robotSelect.value = robots[0] || "";
    const table = this.tableSelect.value;
    this.tables.update(state.tables);
    if (!this.tablePicked || !state.tables.includes(table)) this.pickNearestTable();
    this.follow();
  }

  /** The table nearest the chosen robot's home: a short trip. */
  pickNearestTable() {
    const r = this.live.robots.get(this.robotSelect.value);
    const home = r && this.live.waypoints.get(r.home);
    const tables = placesState(this.live).tables.map((name) => this.live.waypoints.get(name));
    if (!tables.length) return;
    const far = (w) => (home ? Math.hypot(w.x - home.x, w.y - home.y) : 0);
    this.tableSelect.value = tables.reduce((a, b) => (far(b) < far(a) ? b : a)).name;
  }

  gone() {
    if (this.trip && !this.trip.end && this.trip.task !== null && !this.live.orders.has(this.trip.order)) {
      this.setTrip({ ...this.trip, end: "over" });
    }
  }

  setTrip(trip) {
    this.trip = trip;
    store(trip);
    this.follow();
  }

  async send() {
    const robot = this.robotSelect.value;
    const table = this.tableSelect.value;
    const r = this.live.robots.get(robot);
    if (!r || !table) return;
    say(null);
    if (!WAKE.has(r.status) || (r.status === "Transit" && r.mode !== "auto")) {
      say("setup.trip.busy", { robot, status: statusName(r.status) });
      return;
    }
    this.sendBtn.disabled = true;
    try {
      if (r.status === "Manual") await this.conn.request({ clientmsg: "ready", robot });
      if (r.status === "Manual" || r.status === "Ready") await this.conn.request({ clientmsg: "control", robot, action: "auto" });
      const dish = t("setup.trip.dish");
      const made = await this.conn.request(
        { clientmsg: "create", type: "order", dish, table, key: newKey("setup-dish") },
        { resend: true },
      );
      this.setTrip({ order: made.order.id, task: null, robot, table, end: null });
      let cart;
      try {
        cart = await this.conn.request(
          { clientmsg: "create", type: "task", orders: [made.order.id], key: newKey("setup-trip") },
          { resend: true },
        );
      } catch (err) {
        // No trip (a table robots cannot reach, ...): the test dish does not stay at the pass.
        this.conn.request({ clientmsg: "dish", order: made.order.id, action: "void", status: "pending" }).catch(() => {});
        this.setTrip(null);
        throw err;
      }
      this.setTrip({ ...this.trip, task: cart.tasks[0].id });
    } catch (err) {
      say("setup.failed", { message: describeError(err) });
    } finally {
      this.sendBtn.disabled = false;
      this.follow();
    }
  }

  /** Go or Food collected, naming the trip and stop shown (a late press is refused, `stale`). */
  async press(button, verb) {
    const robot = this.tripRobot();
    if (!robot) return;
    say(null);
    button.disabled = true;
    try {
      await this.conn.request({ clientmsg: verb, robot, ...this.live.target(robot) });
    } catch (err) {
      say("setup.failed", { message: describeError(err) });
    } finally {
      button.disabled = false;
    }
  }

  /** The robot on the trip: the one that took it (another free robot may have been first). */
  tripRobot() {
    const trip = this.trip;
    if (!trip) return null;
    const task = trip.task === null ? null : this.live.tasks.get(trip.task);
    return (task && task.robot) || trip.robot;
  }

  /** The trip's progress (a live region) and what to do now. */
  tell(text, how) {
    if (this.progress.textContent !== text) this.progress.textContent = text;
    if (this.how.textContent !== how) this.how.textContent = how;
  }

  /** The trip's progress in words, from the live robots, trips and dishes. */
  follow() {
    const trip = this.trip;
    let go = false;
    let collected = false;
    const done = () => {
      this.goBtn.hidden = !go;
      this.collectedBtn.hidden = !collected;
      this.sendBtn.disabled = Boolean(trip && !trip.end);
    };
    if (!trip) {
      this.tell("", "");
      return done();
    }
    const robot = this.tripRobot();
    const r = this.live.robots.get(robot);
    const order = this.live.orders.get(trip.order);
    const task = trip.task === null ? null : this.live.tasks.get(trip.task);
    if (order) this.progress.dataset.dish = order.status; // the test dish's status, as last seen
    const where = { robot, table: trip.table };
    const timeout = this.live.settings ? this.live.settings.table_timeout : 180;
    if (order && order.status === "delivered" && !trip.end) trip.end = "delivered";
    if (order && order.status === "returned" && !trip.end) {
      trip.end = "returned";
      // Nobody took the test dish: off the pass list, so staff never send it.
      this.conn.request({ clientmsg: "dish", order: order.id, action: "void", status: "returned" }).catch(() => {});
    }
    if (order && order.status === "voided" && !trip.end) trip.end = "voided";
    if (task && task.status === "cancelled" && !trip.end) {
      trip.end = "cancelled";
      if (order && order.status === "pending") {
        this.conn.request({ clientmsg: "dish", order: order.id, action: "void", status: "pending" }).catch(() => {});
      }
    }
    store(trip);
    if (trip.end === "delivered") {
      const home = r && r.status === "Awaiting";
      this.tell(t(home ? "setup.trip.home" : "setup.trip.delivered", where), t("setup.trip.ready"));
    } else if (trip.end) {
      const key = {
        returned: "setup.trip.returned",
        voided: "setup.trip.voided",
        cancelled: "setup.trip.cancelled",
        over: "setup.trip.over",
      }[trip.end];
      const limit = timeout ? limitWords(timeout) : "";
      this.tell(t(key || "setup.trip.cancelled", { ...where, limit }), t("setup.trip.again"));
    } else if (!r) {
      this.tell(t("setup.trip.noRobot", where), "");
    } else if (r.status === "Offline") {
      this.tell(t("setup.trip.offline", where), t("setup.trip.offlineHow"));
    } else if (!task || task.status === "queued" || r.current_task !== task.id) {
      const key = r.status === "Transit" ? "setup.trip.goingHome" : "setup.trip.waiting";
      this.tell(t(key, { ...where, status: statusName(r.status) }), "");
    } else if (r.status === "Loading") {
      go = true;
      this.tell(t("setup.trip.loading", where), t("setup.trip.loadingHow"));
    } else if (r.status === "Delivering") {
      this.tell(t("setup.trip.delivering", where), "");
    } else if (r.status === "Delivered") {
      collected = true;
      const how = timeout
        ? t("setup.trip.atTableHow", { ...where, limit: limitWords(timeout) })
        : t("setup.trip.atTableForever", where);
      this.tell(t("setup.trip.atTable", where), how);
    } else if (r.status === "Stopped" || r.status === "Error") {
      this.tell(t("setup.trip.stuck", { ...where, status: statusName(r.status), why: r.last_error || "" }), t("setup.trip.stuckHow"));
    } else {
      this.tell(t("setup.trip.status", { ...where, status: statusName(r.status) }), "");
    }
    return done();
  }
}
