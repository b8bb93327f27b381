// The page's copy of the server's state, kept from snapshots and updates (docs/protocol.md,
// "Topics"). State topics are upserts keyed by name or id; streams keep the latest value.
// Emits "change" {topic, record} after every change (record: the updated record, or null after a
// snapshot), so views redraw only what they show. A robot or waypoint update with `removed: true`
// (the owner removed or renamed it) drops that record, as does a removed zone (and its lease row).
// Single-value topics are kept whole: `map`, `settings` (the site's settings) and `forecast` (the
// owner's "how many robots" forecast). Only `pose:<robot>`, `scan:<robot>` and `cloud:<robot>`
// are per-robot streams; any other topic is not filed under a robot.

const KEYS = {
  robots: "name", waypoints: "name", orders: "id", tasks: "id", events: "id",
  alerts: "id", menu: "dish", blocks: "table", zones: "name", leases: "zone",
};
const MAX_EVENTS = 200;
// Topics whose one value is kept whole in this[topic] (null: none yet, or none loaded).
const SINGLE = ["map", "settings", "forecast"];
// Per-robot streams, `<kind>:<robot>`: kind -> the Live table holding each robot's latest value.
const ROBOT_STREAMS = { pose: "poses", scan: "scans", cloud: "clouds" };

export class Live extends EventTarget {
  constructor(conn) {
    super();
    this.conn = conn;
    this.robots = new Map();
    this.waypoints = new Map();
    this.orders = new Map();
    this.tasks = new Map();
    this.events = new Map();
    this.alerts = new Map(); // active alerts only: a cleared one is removed
    this.menu = new Map(); // dish name -> menu item
    this.blocks = new Map(); // table -> why no robot is sent there
    this.zones = new Map(); // zone name -> {name, points, capacity} (zones robots take turns through)
    this.leases = new Map(); // zone name -> {zone, capacity, holders, waiting}
    this.map = null;
    this.settings = null; // the site's settings, if the page subscribed to them
    this.forecast = null; // the owner's latest fleet forecast, if the page subscribed to it
    this.poses = new Map(); // robot -> {x, y, yaw, stamp}
    this.scans = new Map(); // robot -> scan
    this.clouds = new Map(); // robot -> its localisation particles, while shown
    this.clock = new ServerClock();
    conn.addEventListener("snapshot", (e) => this._snapshot(e.detail.data));
    conn.addEventListener("update", (e) => this._update(e.detail.topic, e.detail.data));
  }

  _snapshot(data) {
    for (const [topic, snap] of Object.entries(data)) {
      if (topic in KEYS) {
        const table = this[topic];
        table.clear(); // a snapshot replaces what we had: it is newer than any update before it
        for (const rec of snap) this._put(topic, rec);
      } else {
        this._stream(topic, snap);
      }
      this._changed(topic);
    }
  }

  _update(topic, data) {
    if (topic in KEYS) this._put(topic, data);
    else this._stream(topic, data);
    this._changed(topic, data);
  }

  _put(topic, rec) {
    // An alert whose cause ended, a block whose reason is gone: over, not shown any more.
    const over = (topic === "alerts" && rec.cleared_at !== null && rec.cleared_at !== undefined) || (topic === "blocks" && !rec.reason);
    const removed = (topic === "robots" || topic === "waypoints" || topic === "zones") && rec.removed === true;
    if (over || removed) this[topic].delete(rec[KEYS[topic]]);
    else this[topic].set(rec[KEYS[topic]], rec);
    if (removed && topic === "zones") this.leases.delete(rec.name); // its leases ended with it
    if (removed && topic === "robots") {
      [this.poses, this.scans, this.clouds].forEach((m) => m.delete(rec.name));
      // Its streams ended with it: not asked for again on the next reconnect.
      for (const kind of Object.keys(ROBOT_STREAMS)) this.conn.topics?.delete(`${kind}:${rec.name}`);
    }
    if (topic === "events" && this.events.size > MAX_EVENTS) {
      this.events.delete(this.events.keys().next().value);
    }
    this.clock.saw(rec.updated_at ?? rec.ts ?? rec.ready_at ?? rec.cleared_at ?? rec.raised_at);
  }

  _stream(topic, data) {
    if (SINGLE.includes(topic)) {
      this[topic] = data ?? null;
      return;
    }
    const [kind, robot] = splitTopic(topic);
    const table = robot && Object.hasOwn(ROBOT_STREAMS, kind) ? this[ROBOT_STREAMS[kind]] : null;
    if (!table) return; // not a robot's stream (audit, a topic this page does not keep): views read the change event
    // A frame already on its way when the page unsubscribed: the stream is not shown any more.
    if (this.conn.topics && !this.conn.topics.has(topic)) return;
    if (data === null) table.delete(robot);
    else {
      table.set(robot, data);
      this.clock.saw(data.stamp);
    }
  }

  _changed(topic, record = null) {
    this.dispatchEvent(new CustomEvent("change", { detail: { topic, record } }));
  }

  /** Where the robot is: its pose stream if subscribed, else the robot record. */
  pose(name) {
    const p = this.poses.get(name);
    if (p) return p;
    const r = this.robots.get(name);
    return r && r.x !== null && r.x !== undefined ? { x: r.x, y: r.y, yaw: r.yaw } : null;
  }

  /**
   * The trip and stop this page shows robot `name` on, for a command to name (docs/protocol.md):
   * the server refuses it (`stale`) if the robot has moved on since, instead of acting on a
   * stop this page does not show.
   */
  target(name) {
    const r = this.robots.get(name);
    if (!r) return {};
    const target = { task: r.current_task ?? null };
    const task = target.task === null ? null : this.tasks.get(target.task);
    const stop = task && task.stops[task.current_stop];
    if (stop) target.stop = stop.seq;
    return target;
  }

  /** The table a robot is heading to or waiting at, from its current task, or null. */
  destination(name) {
    const r = this.robots.get(name);
    if (!r || r.current_task === null) return null;
    const task = this.tasks.get(r.current_task);
    const stop = task && task.stops[task.current_stop];
    return stop ? stop.table : null;
  }

  /**
   * What goes on which tray of a trip: tray k holds the dishes of stop seq k-1 (stops are in
   * visiting order). [{tray, seq, table, status, orders: [order records]}].
   */
  trays(taskId) {
    const task = taskId === null || taskId === undefined ? null : this.tasks.get(taskId);
    if (!task) return [];
    return task.stops.map((s) => ({
      tray: s.seq + 1,
      seq: s.seq,
      table: s.table,
      status: s.status,
      orders: s.orders.map((id) => this.orders.get(id)).filter(Boolean),
    }));
  }
}

export function splitTopic(topic) {
  const i = topic.indexOf(":");
  return i < 0 ? [topic, ""] : [topic.slice(0, i), topic.slice(i + 1)];
}

/**
 * The server's clock, estimated from the timestamps it sends. The protocol's times are on the
 * server's clock (which may run faster than real time in a demo), so "waiting for 3 min" must
 * be measured against it, not against the tablet's clock.
 */
export class ServerClock {
  constructor() {
    this._server = null;
    this._local = 0;
  }

  saw(ts) {
    if (typeof ts !== "number" || !Number.isFinite(ts)) return;
    if (this._server === null || ts > this._server) {
      this._server = ts;
      this._local = performance.now();
    }
  }

  now() {
    if (this._server === null) return Date.now() / 1000;
    return this._server + (performance.now() - this._local) / 1000;
  }
}
