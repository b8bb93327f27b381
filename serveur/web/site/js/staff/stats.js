// Statistics (the owner's): how past services went, from the server's records, through the
// protocol's `stats` verb (the very figures `serveur stats` prints: docs/statistics.md).
//
// A range (today, yesterday, the last 7 days, or from one date to another: service days, which
// start at 04:00) grouped by hour or by day; the range's headline figures; two charts drawn here
// as inline SVG (dishes delivered, and the wait within which 95 % of dishes were served, per
// period), each with a text alternative (an aria-label summary, and the figures as a table);
// each robot's share of the work; the trip history, each trip opening onto its stops and
// dishes; and both as CSV files built here, with the columns `serveur stats --csv` writes.
//
// "How many robots do I need?": a past service day's dishes replayed by the server (`stats`
// `forecast`: a `serveur replay` child per fleet size, one after the other) with the fleet
// sizes ticked; each fleet's step and result arrive on the `forecast` topic, shown as words,
// a table and a bar chart of the 95 % wait, the fleet the site has now marked.
//
// Times are shown on the restaurant's clock as this device knows it: the request names this
// device's UTC offset, and every time is written with that same offset, so the periods, the
// times and the CSV agree with `serveur stats --utc-offset` on the server.

import { el, showError } from "../ui.js";
import { lang, onLangChange, t } from "../i18n.js";

const SVG = "http://www.w3.org/2000/svg";
const DAY_START = 4; // a service day runs from 04:00 to 04:00 (serveur stats --day-start)
const RELOAD_AFTER_MS = 60_000; // the tab opened again later than this: the figures are fetched anew
const STATS_TIMEOUT_MS = 130_000; // the server gives a computation up to 120 s
const TRIPS_PAGE = 50; // trips listed at first, and more at each "Show more"
const HTML_LANG = { en: "en", zh: "zh-Hans", ms: "ms" };
const FLEET_SIZES = [1, 2, 3, 4, 5, 6]; // the fleet sizes an owner may try in a forecast
// A forecast's fleet states, in the order they go through (a record never goes back).
const FLEET_STEP = { waiting: 0, running: 1, done: 2, failed: 2, cancelled: 2 };
const FLEET_PROGRESS = {
  waiting: "stats.fc.progress.waiting",
  running: "stats.fc.progress.running",
  done: "stats.fc.progress.done",
  failed: "stats.fc.progress.failed",
  cancelled: "stats.fc.progress.cancelled",
};

// The CSV's columns, as serveur/stats/cli.py writes them (figure_rows, trip_rows).
const FIELDS = [
  "delivered", "wait_mean", "wait_p50", "wait_p95", "wait_max", "pass_mean", "pass_p95",
  "pass_max", "loading_s", "loading_per_trip", "trips", "trips_cancelled", "tables_per_trip",
  "dishes_per_trip", "returned", "resent", "voided", "table_timeouts", "staff_skips",
  "busy_share", "errors", "link_drops", "distance_m",
];
const ROBOT_FIELDS = ["busy_s", "busy_share", "loading_s", "trips", "errors", "distance_m"];
// Counts are whole numbers in the command's CSV; every other figure is a float ("15.0").
const COUNTS = new Set([
  "delivered", "trips", "trips_cancelled", "returned", "resent", "voided", "table_timeouts",
  "staff_skips", "errors", "link_drops",
]);
const TRIP_COLUMNS = [
  "trip", "robot", "status", "created", "started", "left_pass", "ended", "loading_s", "stop",
  "table", "arrived", "stop_ended", "outcome", "reason", "by", "at_table_s", "dishes",
];

const RANGES = [
  ["today", "stats.range.today"],
  ["yesterday", "stats.range.yesterday"],
  ["week", "stats.range.week"],
  ["custom", "stats.range.custom"],
];
const TRIP_STATUS = {
  queued: "stats.trip.queued",
  active: "stats.trip.active",
  done: "stats.trip.done",
  cancelled: "stats.trip.cancelled",
};

// -- numbers, dates and times ----------------------------------------------------------------

function locale() {
  return HTML_LANG[lang()] || "en";
}

function fmt(value, options = {}) {
  return new Intl.NumberFormat(locale(), options).format(value);
}

const DASH = "–";

function count(v) {
  return v === null || v === undefined ? DASH : fmt(v, { maximumFractionDigits: 0 });
}

function one(v) {
  return v === null || v === undefined ? DASH : fmt(v, { maximumFractionDigits: 1, minimumFractionDigits: 1 });
}

/** Seconds as minutes: "7.3 min". */
function minutes(s) {
  if (s === null || s === undefined) return DASH;
  return fmt(s / 60, { style: "unit", unit: "minute", unitDisplay: "short", maximumFractionDigits: 1 });
}

/** A short time span as people say it: "45 s" under a minute and a half, else "7.3 min". */
function duration(s) {
  if (s === null || s === undefined) return DASH;
  if (s < 90) return fmt(Math.round(s), { style: "unit", unit: "second", unitDisplay: "short" });
  return minutes(s);
}

/** Seconds as hours and minutes for long spans (busy time): "2 h 05 min". */
function span(s) {
  if (s === null || s === undefined) return DASH;
  const m = Math.round(s / 60);
  if (m < 60) return minutes(s);
  return t("stats.hoursMinutes", { h: fmt(Math.floor(m / 60)), m: String(m % 60).padStart(2, "0") });
}

function percent(v) {
  return v === null || v === undefined ? DASH : fmt(v, { style: "percent", maximumFractionDigits: 0 });
}

function distance(m) {
  if (m === null || m === undefined) return DASH;
  if (m >= 1000) return fmt(m / 1000, { style: "unit", unit: "kilometer", unitDisplay: "short", maximumFractionDigits: 1 });
  return fmt(m, { style: "unit", unit: "meter", unitDisplay: "short", maximumFractionDigits: 0 });
}

/** This device's UTC offset (minutes) at a local date ("2026-11-24"), and as "+08:00". */
function offsetAt(date) {
  const [y, mo, d] = date.split("-").map(Number);
  return -new Date(y, mo - 1, d, 12).getTimezoneOffset();
}

function offsetText(minutes_) {
  const sign = minutes_ < 0 ? "-" : "+";
  const a = Math.abs(minutes_);
  return `${sign}${String(Math.floor(a / 60)).padStart(2, "0")}:${String(a % 60).padStart(2, "0")}`;
}

/** A Date whose UTC fields are the restaurant's clock at epoch `ts` (microseconds kept, as
 *  Python's datetime.fromtimestamp does). */
function wall(ts, offset) {
  const us = Math.round((ts + offset * 60) * 1e6);
  return new Date(Math.floor(us / 1000));
}

const pad = (n, w = 2) => String(n).padStart(w, "0");

/** "2026-11-24 19:32:05", as the command's CSV writes a time ("" for none). */
function csvTime(ts, offset) {
  if (ts === null || ts === undefined) return "";
  const d = wall(ts, offset);
  return `${d.getUTCFullYear()}-${pad(d.getUTCMonth() + 1)}-${pad(d.getUTCDate())} ${pad(d.getUTCHours())}:${pad(d.getUTCMinutes())}:${pad(d.getUTCSeconds())}`;
}

function clock(ts, offset) {
  if (ts === null || ts === undefined) return DASH;
  return new Intl.DateTimeFormat(locale(), { timeZone: "UTC", hour: "2-digit", minute: "2-digit" }).format(wall(ts, offset));
}

function dayName(ts, offset) {
  return new Intl.DateTimeFormat(locale(), { timeZone: "UTC", weekday: "short", day: "numeric", month: "short" }).format(wall(ts, offset));
}

/** A date field "2026-11-24" as words: "Tue 24 Nov". */
function dateWords(date) {
  const [y, m, d] = date.split("-").map(Number);
  return new Intl.DateTimeFormat(locale(), { timeZone: "UTC", weekday: "short", day: "numeric", month: "short" }).format(new Date(Date.UTC(y, m - 1, d)));
}

/** A period's label ("2026-11-24" or "2026-11-24 19:00") as a reader says it. */
function periodWords(label, several) {
  const [date, hour] = label.split(" ");
  if (!hour) return dateWords(date);
  return several ? `${dateWords(date)} ${hour}` : hour;
}

function isoDate(d) {
  return `${d.getFullYear()}-${pad(d.getMonth() + 1)}-${pad(d.getDate())}`;
}

/** Today's service day on this device (before 04:00 it is still yesterday's). */
function serviceToday() {
  return new Date(Date.now() - DAY_START * 3600 * 1000);
}

function addDays(d, n) {
  const out = new Date(d);
  out.setDate(out.getDate() + n);
  return out;
}

// -- CSV ---------------------------------------------------------------------------------------

/** Python's round(x, 3): the nearest, ties to even. */
function round3(x) {
  const y = x * 1000;
  let r = Math.round(y);
  if (Math.abs(y - Math.trunc(y)) === 0.5 && r % 2 !== 0) r -= 1;
  return r / 1000;
}

/** A cell as the command writes it: counts as integers, other figures as Python floats. */
function csvNumber(v, isCount) {
  if (v === null || v === undefined || v === "") return "";
  if (isCount) return String(v);
  const r = round3(Number(v));
  return Number.isInteger(r) ? r.toFixed(1) : String(r);
}

function csvCell(v) {
  const s = String(v);
  return /[",\r\n]/.test(s) ? `"${s.replaceAll('"', '""')}"` : s;
}

function csvText(head, rows) {
  if (!rows.length) return "";
  return [head, ...rows].map((r) => r.map(csvCell).join(",")).join("\n") + "\n";
}

/** The figures as `serveur stats --csv`: a row per period, then the total. */
export function figuresCsv(doc, offset) {
  const robots = doc.total.robots.map((r) => r.robot);
  const head = ["period", "start", "end", ...FIELDS];
  for (const name of robots) head.push(...ROBOT_FIELDS.map((f) => `${f}:${name}`));
  const rows = [...doc.periods, doc.total].map((p) => {
    const row = [p.period, csvTime(p.start, offset), csvTime(p.end, offset)];
    row.push(...FIELDS.map((f) => csvNumber(p[f], COUNTS.has(f))));
    const by = new Map(p.robots.map((r) => [r.robot, r]));
    for (const name of robots) {
      const r = by.get(name) || {};
      const nothing = { busy_s: 0, busy_share: null, loading_s: 0, trips: 0, errors: 0, distance_m: 0 };
      // A robot that drove nowhere has a distance of 0 (an integer: the sum of no steps).
      const whole = (f, v) => f === "trips" || f === "errors" || (f === "distance_m" && v === 0);
      row.push(...ROBOT_FIELDS.map((f) => csvNumber(f in r ? r[f] : nothing[f], whole(f, f in r ? r[f] : nothing[f]))));
    }
    return row;
  });
  return csvText(head, rows);
}

/** The trip history as `serveur stats --trips --csv`: a row per stop. */
export function tripsCsv(doc, offset) {
  const rows = [];
  for (const trip of doc.trips) {
    trip.stops.forEach((s, i) => {
      const atTable = s.ended !== null && s.arrived !== null ? s.ended - s.arrived : "";
      rows.push([
        trip.id,
        trip.robot || "",
        trip.status,
        csvTime(trip.created, offset),
        csvTime(trip.started, offset),
        csvTime(trip.left, offset),
        csvTime(trip.ended, offset),
        csvNumber(trip.loading_s, false),
        i + 1,
        s.table,
        csvTime(s.arrived, offset),
        csvTime(s.ended, offset),
        s.outcome,
        s.reason || "",
        s.by || "",
        csvNumber(atTable, false),
        s.dishes.map((d) => d.order).join(" "),
      ]);
    });
  }
  return csvText(TRIP_COLUMNS, rows);
}

// -- charts --------------------------------------------------------------------------------------

function svg(tag, attrs = {}, ...children) {
  const node = document.createElementNS(SVG, tag);
  for (const [k, v] of Object.entries(attrs)) if (v !== null && v !== undefined) node.setAttribute(k, String(v));
  for (const c of children) if (c) node.append(c instanceof Node ? c : document.createTextNode(String(c)));
  return node;
}

/** About how wide `text` is at 12 px (CJK characters are about twice as wide). */
function textWidth(text) {
  let w = 0;
  for (const ch of text) w += /[\u2e80-\uffef]/.test(ch) ? 12 : 7;
  return w;
}

/** A round top for an axis: 1, 2, 5 times a power of ten, at least `max`. */
function niceTop(max) {
  if (!(max > 0)) return 1;
  const p = 10 ** Math.floor(Math.log10(max));
  for (const m of [1, 2, 5, 10]) if (m * p >= max) return m * p;
  return 10 * p;
}

/**
 * A chart of one value per period: bars, or a line with a dot per period (null: no dot, the
 * line broken). `labels` name the periods; `tick` writes an axis value. Drawn to `width` px.
 */
function chart({ kind, values, labels, tick, width, label }) {
  const height = 220;
  const top_ = niceTop(Math.max(0, ...values.filter((v) => v !== null)));
  // The middle line only where it is a round value (no "2.5 dishes").
  const ticks = kind === "bars" && !Number.isInteger(top_ / 2) ? [0, top_] : [0, top_ / 2, top_];
  const tickText = ticks.map((v) => tick(v));
  const left = 12 + Math.max(...tickText.map(textWidth)); // room for the longest
  const right = 10;
  const top = 18;
  const bottom = 34;
  const w = Math.max(200, width);
  const plotW = w - left - right;
  const plotH = height - top - bottom;
  const y = (v) => top + plotH - (v / top_) * plotH;
  const band = plotW / Math.max(1, values.length);
  const root = svg("svg", { class: `chart chart-${kind}`, viewBox: `0 0 ${w} ${height}`, width: w, height, role: "img", "aria-label": label });
  const grid = svg("g", { class: "chart-grid", "aria-hidden": "true" });
  ticks.forEach((v, i) => {
    grid.append(
      svg("line", { x1: left, x2: w - right, y1: y(v), y2: y(v) }),
      svg("text", { x: left - 6, y: y(v) + 4, "text-anchor": "end" }, tickText[i]),
    );
  });
  root.append(grid);
  // Period names under the plot, thinned so that they do not overlap.
  const room = Math.max(1, ...labels.map(textWidth)) + 12;
  const every = Math.max(1, Math.ceil(values.length / Math.max(1, Math.floor(plotW / room))));
  const axis = svg("g", { class: "chart-axis", "aria-hidden": "true" });
  labels.forEach((text, i) => {
    if (i % every) return;
    // Centred under its period, kept inside the picture at either end.
    let x = left + band * (i + 0.5);
    let anchor = "middle";
    const half = textWidth(text) / 2;
    if (x - half < 2) [x, anchor] = [2, "start"];
    else if (x + half > w - 2) [x, anchor] = [w - 2, "end"];
    axis.append(svg("text", { x, y: height - bottom + 18, "text-anchor": anchor }, text));
  });
  root.append(axis);
  const marks = svg("g", { class: "chart-marks" });
  if (kind === "bars") {
    const bw = Math.max(2, Math.min(48, band * 0.7));
    const numbers = svg("g", { class: "chart-values", "aria-hidden": "true" });
    values.forEach((v, i) => {
      const h = v ? plotH - (y(v) - top) : 0;
      if (band >= 24 && v) numbers.append(svg("text", { x: left + band * (i + 0.5), y: top + plotH - h - 4, "text-anchor": "middle" }, tick(v)));
      marks.append(
        svg(
          "rect",
          { class: "bar", x: left + band * (i + 0.5) - bw / 2, y: top + plotH - h, width: bw, height: Math.max(h, 0), "data-value": v },
          svg("title", {}, `${labels[i]}: ${tick(v ?? 0)}`),
        ),
      );
    });
    root.append(numbers);
  } else {
    let path = "";
    values.forEach((v, i) => {
      if (v === null) return;
      const x = left + band * (i + 0.5);
      const start = i === 0 || values[i - 1] === null;
      path += `${start ? "M" : "L"}${x.toFixed(1)},${y(v).toFixed(1)} `;
    });
    if (path) marks.append(svg("path", { class: "line", d: path.trim() }));
    values.forEach((v, i) => {
      if (v === null) return;
      marks.append(svg("circle", { class: "dot", cx: left + band * (i + 0.5), cy: y(v), r: 4 }, svg("title", {}, `${labels[i]}: ${tick(v)}`)));
    });
  }
  root.append(marks);
  return root;
}

/**
 * "How many robots?": one bar per fleet size tried, as tall as the wait within which 95 % of
 * the replayed day's dishes reached the table (minutes); the fleet the site has now marked.
 * A fleet still replaying (or failed) keeps its place, with no bar.
 */
function fleetChart({ fleets, current, width, label }) {
  const height = 200;
  const values = fleets.map((f) => (f.state === "done" && f.wait_p95 !== null && f.wait_p95 !== undefined ? f.wait_p95 / 60 : null));
  const top_ = niceTop(Math.max(0, ...values.filter((v) => v !== null)));
  const ticks = [0, top_ / 2, top_];
  const tickText = ticks.map((v) => fmt(v, { maximumFractionDigits: 1 }));
  const left = 12 + Math.max(...tickText.map(textWidth));
  const right = 10;
  const top = 20;
  const bottom = 44; // the fleet size, and "now" under the current one
  const w = Math.max(200, width);
  const plotW = w - left - right;
  const plotH = height - top - bottom;
  const y = (v) => top + plotH - (v / top_) * plotH;
  const band = plotW / Math.max(1, fleets.length);
  const bw = Math.max(8, Math.min(56, band * 0.6));
  const root = svg("svg", { class: "chart chart-fleets", viewBox: `0 0 ${w} ${height}`, width: w, height, role: "img", "aria-label": label });
  const grid = svg("g", { class: "chart-grid", "aria-hidden": "true" });
  ticks.forEach((v, i) => {
    grid.append(svg("line", { x1: left, x2: w - right, y1: y(v), y2: y(v) }), svg("text", { x: left - 6, y: y(v) + 4, "text-anchor": "end" }, tickText[i]));
  });
  root.append(grid);
  const axis = svg("g", { class: "chart-axis", "aria-hidden": "true" });
  const numbers = svg("g", { class: "chart-values", "aria-hidden": "true" });
  const marks = svg("g", { class: "chart-marks" });
  fleets.forEach((f, i) => {
    const x = left + band * (i + 0.5);
    const now = f.robots === current;
    const name = t("stats.fc.fleet", { count: f.robots });
    axis.append(svg("text", { x, y: height - bottom + 18, "text-anchor": "middle", class: now ? "now" : null }, textWidth(name) + 4 <= band ? name : fmt(f.robots)));
    if (now) axis.append(svg("text", { x, y: height - bottom + 34, "text-anchor": "middle", class: "now" }, t("stats.fc.now")));
    const v = values[i];
    if (v === null) return;
    const h = plotH - (y(v) - top);
    numbers.append(svg("text", { x, y: top + plotH - h - 4, "text-anchor": "middle" }, fmt(v, { maximumFractionDigits: 1, minimumFractionDigits: 1 })));
    marks.append(
      svg(
        "rect",
        { class: now ? "bar now" : "bar", x: x - bw / 2, y: top + plotH - h, width: bw, height: Math.max(h, 0), "data-robots": f.robots, "data-value": f.wait_p95 },
        svg("title", {}, `${name}: ${minutes(f.wait_p95)}`),
      ),
    );
  });
  root.append(axis, numbers, marks);
  return root;
}

/** How far a forecast record has got: each fleet's step, and the forecast's end. */
function fcStep(fc) {
  return fc.fleets.reduce((n, f) => n + (FLEET_STEP[f.state] ?? 0), 0) + (fc.state === "running" ? 0 : 1);
}

/** The forecast's state in words: "Replaying… 1 of 2 finished.", "Finished.", … */
function fcStateText(fc) {
  if (fc.state === "running") {
    const finished = fc.fleets.filter((f) => f.state !== "waiting" && f.state !== "running").length;
    return t("stats.fc.state.running", { done: fmt(finished), total: fmt(fc.fleets.length) });
  }
  if (fc.state === "done") return t("stats.fc.state.done");
  if (fc.state === "cancelled") return t("stats.fc.state.cancelled");
  return fc.error ? t("stats.fc.state.failedWhy", { error: fc.error }) : t("stats.fc.state.failed");
}

// -- the panel -------------------------------------------------------------------------------------

let ids = 0;

export class StatsPanel {
  constructor(root, conn, live) {
    this.root = root;
    this.conn = conn;
    this.live = live;
    this.figures = null; // the last `figures` reply, with what was asked
    this.trips = null;
    this.asked = null; // {start, end, by, offset, range}
    this.loadedAt = 0;
    this.seq = 0; // the latest load: an older reply arriving late is dropped
    const id = (name) => `stats-${name}-${++ids}`;

    // -- what to show
    this.range = el("select", { id: id("range"), name: "range" });
    this.by = el("select", { id: id("by"), name: "by" });
    const today = isoDate(serviceToday());
    this.from = el("input", { id: id("from"), name: "from", type: "date", value: today, max: today, required: true });
    this.to = el("input", { id: id("to"), name: "to", type: "date", value: today, max: today, required: true });
    this.custom = el(
      "div",
      { class: "stats-custom", hidden: true },
      el("span", { class: "stats-field" }, el("label", { for: this.from.id, "data-i18n": "stats.from" }), this.from),
      el("span", { class: "stats-field" }, el("label", { for: this.to.id, "data-i18n": "stats.to" }), this.to),
    );
    this.showBtn = el("button", { type: "submit", class: "primary", "data-needs-online": true, "data-i18n": "stats.show" });
    this.form = el(
      "form",
      { class: "card stats-controls", "data-i18n-aria-label": "stats.controls" },
      el("div", { class: "stats-field" }, el("label", { for: this.range.id, "data-i18n": "stats.range" }), this.range),
      this.custom,
      el("div", { class: "stats-field" }, el("label", { for: this.by.id, "data-i18n": "stats.by" }), this.by),
      el("div", { class: "stats-go" }, this.showBtn),
    );
    this.form.addEventListener("submit", (e) => {
      e.preventDefault();
      this.load();
    });
    this.range.addEventListener("change", () => {
      const preset = this.range.value;
      this.custom.hidden = preset !== "custom";
      if (preset === "custom") return; // the dates, then Show
      this.by.value = preset === "week" ? "day" : "hour"; // a day by the hour, a week by the day
      this.load();
    });
    this.by.addEventListener("change", () => this.load());

    // -- what was found
    this.state = el("p", { class: "stats-state", role: "status", "aria-live": "polite" });
    this.heading = el("h2", { class: "stats-heading", tabindex: "-1" });
    this.tiles = el("dl", { class: "stats-tiles" });
    this.deliveredChart = el("div", { class: "chart-box" });
    this.waitChart = el("div", { class: "chart-box" });
    // On a phone the tables scroll sideways inside their box: a keyboard can scroll it too.
    const scroller = (key) => el("div", { class: "table-scroll", tabindex: "0", role: "region", "data-i18n-aria-label": key });
    this.periodTable = scroller("stats.table.caption");
    this.robotTable = scroller("stats.robots.title");
    this.tripList = el("ul", { class: "stats-trips", "data-i18n-aria-label": "stats.trips.title" });
    this.tripNote = el("p", { class: "muted stats-trip-note" });
    this.tripsShown = TRIPS_PAGE;
    this.moreTrips = el("button", {
      type: "button",
      class: "secondary",
      hidden: true,
      onclick: () => {
        this.tripsShown += TRIPS_PAGE;
        this._trips();
      },
    });
    this.figuresCsvBtn = el("button", { type: "button", class: "secondary", "data-i18n": "stats.csv.figures", onclick: () => this._download("figures") });
    this.tripsCsvBtn = el("button", { type: "button", class: "secondary", "data-i18n": "stats.csv.trips", onclick: () => this._download("trips") });
    const deliveredTitle = id("delivered-title");
    const waitTitle = id("wait-title");
    const robotsTitle = id("robots-title");
    const tripsTitle = id("trips-title");
    this.heading.id = id("heading");
    this.results = el(
      "div",
      { class: "stats-results", hidden: true },
      el(
        "section",
        { class: "card stats-summary", "aria-labelledby": this.heading.id },
        this.heading,
        this.tiles,
        el("div", { class: "stats-downloads" }, this.figuresCsvBtn, this.tripsCsvBtn),
      ),
      el(
        "div",
        { class: "stats-charts" },
        el("section", { class: "card", "aria-labelledby": deliveredTitle }, el("h3", { id: deliveredTitle, "data-i18n": "stats.chart.delivered" }), this.deliveredChart),
        el(
          "section",
          { class: "card", "aria-labelledby": waitTitle },
          el("h3", { id: waitTitle, "data-i18n": "stats.chart.wait" }),
          el("p", { class: "muted chart-note", "data-i18n": "stats.chart.waitNote" }),
          this.waitChart,
        ),
      ),
      el("details", { class: "card stats-table-details" }, el("summary", { "data-i18n": "stats.table.show" }), this.periodTable),
      el("section", { class: "card", "aria-labelledby": robotsTitle }, el("h3", { id: robotsTitle, "data-i18n": "stats.robots.title" }), this.robotTable),
      el("section", { class: "card", "aria-labelledby": tripsTitle }, el("h3", { id: tripsTitle, "data-i18n": "stats.trips.title" }), el("p", { class: "muted", "data-i18n": "stats.trips.hint" }), this.tripNote, this.tripList, el("div", { class: "form-buttons stats-more" }, this.moreTrips)),
    );
    // -- "How many robots do I need?": a recorded day replayed with other fleet sizes
    this.forecast = null; // the latest forecast record (the `forecast` topic's), or null
    this.fcError = ""; // why the last Start was refused, shown until the next one
    this.fcStarting = false;
    this.fleetsTouched = false; // the owner chose the fleet sizes: no more defaults
    this.dayTouched = false; // the owner chose the day: the range no longer sets it
    this.fcDay = el("input", { id: id("fc-day"), name: "forecast-day", type: "date", value: isoDate(addDays(serviceToday(), -1)), max: today, required: true });
    this.fcDay.addEventListener("input", () => {
      this.dayTouched = true;
    });
    this.fcPicks = FLEET_SIZES.map((n) => {
      const box = el("input", { type: "checkbox", name: "forecast-robots", value: n, id: id(`fc-robots-${n}`) });
      box.addEventListener("change", () => {
        this.fleetsTouched = true;
      });
      const now = el("span", { class: "fc-now", hidden: true, "data-i18n": "stats.fc.now" });
      return { n, box, now, label: el("label", { class: "fc-pick", for: box.id }, box, el("span", { class: "fc-pick-face" }, el("span", { class: "fc-pick-n" }, fmt(n)), now)) };
    });
    const fleetsLegend = id("fc-fleets");
    this.fcStart = el("button", { type: "submit", class: "primary", "data-needs-online": true, "data-i18n": "stats.fc.start" });
    this.fcCancel = el("button", { type: "button", class: "secondary", hidden: true, "data-needs-online": true, "data-i18n": "stats.fc.cancel", onclick: () => this._fcCancelRun() });
    this.fcForm = el(
      "form",
      { class: "fc-controls", "data-i18n-aria-label": "stats.fc.controls" },
      el("div", { class: "stats-field" }, el("label", { for: this.fcDay.id, "data-i18n": "stats.fc.day" }), this.fcDay),
      el("fieldset", { class: "fc-fleets" }, el("legend", { id: fleetsLegend, "data-i18n": "stats.fc.fleets" }), el("div", { class: "fc-picks" }, ...this.fcPicks.map((p) => p.label))),
      el("div", { class: "form-buttons fc-buttons" }, this.fcStart, this.fcCancel),
    );
    this.fcForm.addEventListener("submit", (e) => {
      e.preventDefault();
      this._fcStartRun();
    });
    this.fcMessage = el("p", { class: "fc-message", role: "status", "aria-live": "polite" });
    this.fcHeading = el("h3", { class: "fc-heading" });
    this.fcProgress = el("ol", { class: "fc-progress" });
    this.fcSentences = el("ul", { class: "fc-sentences" });
    this.fcTable = el("div", { class: "table-scroll", tabindex: "0", role: "region", "data-i18n-aria-label": "stats.fc.caption" });
    this.fcChart = el("div", { class: "chart-box fc-chart" });
    const fcChartTitle = id("fc-chart-title");
    this.fcResult = el(
      "div",
      { class: "fc-result", hidden: true },
      this.fcHeading,
      this.fcProgress,
      this.fcSentences,
      el("div", { class: "fc-side" }, this.fcTable, el("div", { class: "fc-chart-wrap" }, el("h4", { id: fcChartTitle, "data-i18n": "stats.fc.chart" }), this.fcChart)),
    );
    const fcTitle = id("fc-title");
    this.fcSection = el(
      "section",
      { class: "card stats-forecast", "aria-labelledby": fcTitle },
      el("h2", { id: fcTitle, "data-i18n": "stats.fc.title" }),
      el("p", { class: "muted fc-explain", "data-i18n": "stats.fc.explain" }),
      this.fcForm,
      this.fcMessage,
      this.fcResult,
    );
    conn.addEventListener("snapshot", (e) => {
      const data = e.detail.data || {};
      if ("forecast" in data) this._fcApply(data.forecast, { snapshot: true });
    });
    conn.addEventListener("update", (e) => {
      if (e.detail.topic === "forecast") this._fcApply(e.detail.data);
    });
    if (live) {
      live.addEventListener("change", (e) => {
        if (e.detail.topic === "robots") this._fcDefaults();
      });
    }
    this._fcDefaults();

    root.append(el("div", { class: "stats-wrap" }, this.form, this.state, this.results, this.fcSection));

    this.drawnWidth = 0;
    new ResizeObserver(() => {
      const w = this.deliveredChart.clientWidth;
      if (this.figures && w && Math.abs(w - this.drawnWidth) > 8) this._charts();
    }).observe(this.deliveredChart);
    this.fcDrawnWidth = 0;
    new ResizeObserver(() => {
      const w = this.fcChart.clientWidth;
      if (this.forecast && w && Math.abs(w - this.fcDrawnWidth) > 8) this._fcChart();
    }).observe(this.fcChart);
    onLangChange(() => {
      this._render();
      this._fcRender();
    });
    this._render();
  }

  /** The tab was opened: fetch the figures the first time, and again when they may be old. */
  shown() {
    const today = isoDate(serviceToday());
    this.from.max = this.to.max = this.fcDay.max = today; // the console may have stayed open overnight
    // The forecast under way or the last one (this console's or another owner's): its record
    // now and each change, kept across reconnections (the owner's alone: scope stats).
    this.conn.subscribe(["forecast"]);
    if (!this.figures || Date.now() - this.loadedAt > RELOAD_AFTER_MS) this.load();
    else this._charts(); // the tab was hidden: the charts are drawn to its width again
    this._fcChart();
  }

  _ask() {
    const preset = this.range.value || "today";
    const day = serviceToday();
    let start;
    let end;
    if (preset === "today") start = end = isoDate(day);
    else if (preset === "yesterday") start = end = isoDate(addDays(day, -1));
    else if (preset === "week") {
      start = isoDate(addDays(day, -6));
      end = isoDate(day);
    } else {
      start = this.from.value;
      end = this.to.value;
    }
    return { range: preset, start, end, by: this.by.value || "hour", offset: offsetAt(start || isoDate(day)) };
  }

  /** Fetch the figures and the trips of the range chosen. */
  async load() {
    const ask = this._ask();
    if (!ask.start || !ask.end || !/^\d{4}-\d{2}-\d{2}$/.test(ask.start) || !/^\d{4}-\d{2}-\d{2}$/.test(ask.end)) {
      this._say(t("stats.state.badDates"));
      return;
    }
    if (ask.end < ask.start) {
      this._say(t("stats.state.endFirst"));
      return;
    }
    const seq = ++this.seq;
    const range = { start: ask.start, end: ask.end, utc_offset: offsetText(ask.offset) };
    this.root.setAttribute("aria-busy", "true");
    this._say(t("stats.state.loading"));
    this.showBtn.disabled = true;
    try {
      const opts = { resend: true, timeout: STATS_TIMEOUT_MS };
      const [figures, trips] = await Promise.all([
        this.conn.request({ clientmsg: "stats", action: "figures", by: ask.by, ...range }, opts),
        this.conn.request({ clientmsg: "stats", action: "trips", ...range }, opts),
      ]);
      if (seq !== this.seq) return;
      if (!this.asked || this.asked.start !== ask.start || this.asked.end !== ask.end) {
        this.tripsShown = TRIPS_PAGE; // another range: its latest trips first
        this.tripList.replaceChildren();
      }
      this.asked = ask;
      this._fcDayFromRange();
      this.figures = figures.stats;
      this.trips = trips.stats;
      this.loadedAt = Date.now();
      this._render();
    } catch (err) {
      if (seq !== this.seq) return;
      showError(err);
      this._say(t("stats.state.failed"));
    } finally {
      if (seq === this.seq) {
        this.root.removeAttribute("aria-busy");
        this.showBtn.disabled = false;
      }
    }
  }

  /** The line that says what is happening (read out by screen readers); `quiet`: read out
   *  only, the figures on screen say it already. */
  _say(text, { quiet = false } = {}) {
    this.state.textContent = text;
    this.state.hidden = !text;
    this.state.classList.toggle("visually-hidden", quiet);
  }

  _render() {
    const range = this.range.value || "today";
    this.range.replaceChildren(...RANGES.map(([v, key]) => el("option", { value: v, text: t(key) })));
    this.range.value = range;
    const by = this.by.value || "hour";
    this.by.replaceChildren(el("option", { value: "hour", text: t("stats.by.hour") }), el("option", { value: "day", text: t("stats.by.day") }));
    this.by.value = by;
    if (!this.figures) {
      this.results.hidden = true;
      return;
    }
    const doc = this.figures;
    const ask = this.asked;
    this.heading.textContent =
      ask.start === ask.end ? t("stats.heading.day", { day: dateWords(ask.start) }) : t("stats.heading.range", { from: dateWords(ask.start), to: dateWords(ask.end) });
    if (!doc.periods.length) {
      this._say(t("stats.state.empty"));
      this.results.hidden = true;
      return;
    }
    this._say(t("stats.state.shown", { what: this.heading.textContent, count: doc.total.delivered }), { quiet: true });
    this.results.hidden = false;
    this._tiles(doc.total);
    this._charts();
    this._periods();
    this._robots(doc.total);
    this._trips();
  }

  _tiles(total) {
    const tile = (key, value, testid) => [el("dt", { "data-i18n": key }), el("dd", { "data-testid": testid }, value)];
    const trips = total.trips_cancelled ? t("stats.tile.tripsCancelled", { trips: count(total.trips), cancelled: count(total.trips_cancelled) }) : count(total.trips);
    const groups = [
      tile("stats.tile.delivered", count(total.delivered), "stats-delivered"),
      tile("stats.tile.waitMean", minutes(total.wait_mean), "stats-wait-mean"),
      tile("stats.tile.waitP95", minutes(total.wait_p95), "stats-wait-p95"),
      tile("stats.tile.pass", duration(total.pass_mean), "stats-pass"),
      tile("stats.tile.returnedVoided", t("stats.tile.returnedVoidedValue", { returned: count(total.returned), voided: count(total.voided) }), "stats-returned"),
      tile("stats.tile.trips", trips, "stats-trips"),
      tile("stats.tile.tablesPerTrip", one(total.tables_per_trip), "stats-tables-per-trip"),
      tile("stats.tile.busy", percent(total.busy_share), "stats-busy"),
      tile("stats.tile.distance", distance(total.distance_m), "stats-distance"),
    ];
    this.tiles.replaceChildren(...groups.map((g) => el("div", { class: "tile" }, ...g)));
  }

  _labels() {
    const doc = this.figures;
    const days = new Set(doc.periods.map((p) => p.period.split(" ")[0]));
    return doc.periods.map((p) => periodWords(p.period, days.size > 1));
  }

  _charts() {
    if (!this.figures || this.results.hidden) return;
    const doc = this.figures;
    const labels = this._labels();
    const width = this.deliveredChart.clientWidth || 320;
    this.drawnWidth = width;
    const delivered = doc.periods.map((p) => p.delivered);
    const most = Math.max(...delivered);
    const busiest = labels[delivered.indexOf(most)];
    this.deliveredChart.replaceChildren(
      chart({
        kind: "bars",
        values: delivered,
        labels,
        width,
        tick: (v) => count(v),
        label: t("stats.chart.deliveredSummary", { count: doc.total.delivered, periods: doc.periods.length, most: count(most), when: busiest }),
      }),
    );
    const waits = doc.periods.map((p) => p.wait_p95);
    const known = waits.filter((v) => v !== null);
    const longest = known.length ? Math.max(...known) : null;
    this.waitChart.replaceChildren(
      chart({
        kind: "line",
        values: waits.map((v) => (v === null ? null : v / 60)), // drawn in minutes: round ticks
        labels,
        width: this.waitChart.clientWidth || width,
        tick: (v) => minutes(v * 60),
        label:
          longest === null
            ? t("stats.chart.waitNone")
            : t("stats.chart.waitSummary", { longest: minutes(longest), when: labels[waits.indexOf(longest)], overall: minutes(doc.total.wait_p95) }),
      }),
    );
  }

  _periods() {
    const doc = this.figures;
    const labels = this._labels();
    const head = ["stats.col.period", "stats.col.delivered", "stats.col.waitMean", "stats.col.waitP95", "stats.col.pass", "stats.col.trips", "stats.col.returned", "stats.col.busy"];
    const row = (label, p, isTotal) =>
      el(
        "tr",
        { class: isTotal ? "total" : null },
        el("th", { scope: "row" }, label),
        el("td", {}, count(p.delivered)),
        el("td", {}, minutes(p.wait_mean)),
        el("td", {}, minutes(p.wait_p95)),
        el("td", {}, duration(p.pass_mean)),
        el("td", {}, count(p.trips)),
        el("td", {}, count(p.returned)),
        el("td", {}, percent(p.busy_share)),
      );
    this.periodTable.replaceChildren(
      el(
        "table",
        { class: "stats-table" },
        el("caption", { "data-i18n": "stats.table.caption" }),
        el("thead", {}, el("tr", {}, ...head.map((k) => el("th", { scope: "col", "data-i18n": k })))),
        el("tbody", {}, ...doc.periods.map((p, i) => row(labels[i], p, false)), row(t("stats.total"), doc.total, true)),
      ),
    );
  }

  _robots(total) {
    if (!total.robots.length) {
      this.robotTable.replaceChildren(el("p", { class: "muted", "data-i18n": "stats.robots.none" }));
      return;
    }
    const head = ["stats.col.robot", "stats.col.trips", "stats.col.busyShare", "stats.col.busyTime", "stats.col.distance", "stats.col.errors", "stats.col.linkDrops"];
    this.robotTable.replaceChildren(
      el(
        "table",
        { class: "stats-table stats-robots" },
        el("caption", { class: "visually-hidden", "data-i18n": "stats.robots.title" }),
        el("thead", {}, el("tr", {}, ...head.map((k) => el("th", { scope: "col", "data-i18n": k })))),
        el(
          "tbody",
          {},
          ...total.robots.map((r) =>
            el(
              "tr",
              {},
              el("th", { scope: "row" }, r.robot),
              el("td", {}, count(r.trips)),
              el("td", {}, percent(r.busy_share)),
              el("td", {}, span(r.busy_s)),
              el("td", {}, distance(r.distance_m)),
              el("td", {}, count(r.errors)),
              el("td", {}, count(r.link_drops)),
            ),
          ),
        ),
      ),
    );
  }

  _trips() {
    const doc = this.trips;
    const offset = this.asked.offset;
    const several = new Set(doc.trips.map((tr) => csvTime(tr.started ?? tr.created, offset).slice(0, 10))).size > 1;
    this.tripNote.textContent = doc.more ? t("stats.trips.more", { count: doc.trips.length }) : doc.trips.length ? "" : t("stats.trips.none");
    this.tripNote.hidden = !this.tripNote.textContent;
    // Newest first: the trip an owner asks about is usually a recent one. Opened ones stay open.
    const open = new Set([...this.tripList.querySelectorAll("details[open]")].map((d) => d.dataset.trip));
    const trips = [...doc.trips].reverse();
    const shown = trips.slice(0, this.tripsShown);
    this.tripList.replaceChildren(...shown.map((trip) => this._trip(trip, offset, several, open.has(String(trip.id)))));
    const left = trips.length - shown.length;
    this.moreTrips.hidden = left <= 0;
    this.moreTrips.textContent = t("stats.trips.showMore", { count: Math.min(left, TRIPS_PAGE) });
  }

  _trip(trip, offset, several, open) {
    const when = trip.started ?? trip.created;
    const whenText = several ? `${dayName(when, offset)} ${clock(when, offset)}` : clock(when, offset);
    const robot = trip.robot || t("stats.trip.noRobot");
    const status = TRIP_STATUS[trip.status] ? t(TRIP_STATUS[trip.status]) : trip.status;
    // Spaces between the parts: the summary is read out as one line.
    const parts = [
      el("span", { class: "trip-time" }, whenText),
      el("span", { class: "trip-id" }, t("stats.trip.name", { id: trip.id })),
      el("span", { class: "trip-robot" }, robot),
      el("span", { class: "trip-what" }, t("stats.trip.tables", { count: trip.stops.length }), ", ", t("stats.trip.delivered", { count: trip.delivered })),
      trip.returned ? el("span", { class: "trip-returned" }, t("stats.trip.returned", { count: trip.returned })) : null,
      el("span", { class: `trip-status trip-${trip.status}` }, status),
    ].filter(Boolean);
    const summary = el("summary", {}, ...parts.flatMap((p, i) => (i ? [" ", p] : [p])));
    const facts = [
      [t("stats.trip.created"), clock(trip.created, offset)],
      [t("stats.trip.started"), clock(trip.started, offset)],
      [t("stats.trip.left"), clock(trip.left, offset)],
      [t("stats.trip.ended"), clock(trip.ended, offset)],
      [t("stats.trip.loading"), duration(trip.loading_s)],
    ];
    if (trip.handed_over.length) facts.push([t("stats.trip.handedOver"), trip.handed_over.join(", ")]);
    const stops = el(
      "ol",
      { class: "trip-stops" },
      ...trip.stops.map((s) =>
        el(
          "li",
          { class: `stop stop-${s.outcome}` },
          el("span", { class: "table-tag" }, t("stats.stop.table", { table: s.table })),
          el("span", { class: "stop-when" }, t("stats.stop.arrived", { time: clock(s.arrived, offset) })),
          el("span", { class: "stop-outcome" }, this._outcome(s, offset)),
          el("span", { class: "stop-dishes" }, s.dishes.length ? s.dishes.map((d) => t("stats.stop.dish", { order: d.order, dish: d.dish || "?" })).join(", ") : DASH),
        ),
      ),
    );
    return el(
      "li",
      {},
      el(
        "details",
        { class: "trip-row", "data-trip": trip.id, open },
        summary,
        el("dl", { class: "trip-facts" }, ...facts.map(([k, v]) => el("div", {}, el("dt", {}, k), el("dd", {}, v)))),
        stops,
      ),
    );
  }

  _outcome(s, offset) {
    const time = clock(s.ended, offset);
    if (s.outcome === "done") return t("stats.stop.done", { time });
    if (s.outcome === "cancelled") return t("stats.stop.cancelled", { time });
    if (s.outcome === "skipped" && s.by) return t("stats.stop.skippedBy", { time, who: s.by.replace(/^user:/, "") });
    if (s.outcome === "skipped") return t("stats.stop.timedOut", { time });
    return t("stats.stop.pending");
  }

  // -- "How many robots do I need?" ------------------------------------------------------------

  /** The robots the site has now (registered, whatever their state): the fleet to compare. */
  _fleetNow() {
    return this.live && this.live.robots ? this.live.robots.size : 0;
  }

  /** Until the owner picks: the fleet now −1, the same, +1 and +2 (within 1..6); the current
   *  size marked "now" on its box. */
  _fcDefaults() {
    const current = this._fleetNow();
    const wanted = new Set([current - 1, current, current + 1, current + 2]);
    for (const p of this.fcPicks) {
      if (!this.fleetsTouched) p.box.checked = wanted.has(p.n);
      p.now.hidden = p.n !== current;
    }
    if (this.forecast) this._fcRender();
  }

  /** The day to replay follows the range while it is one past day; else yesterday. */
  _fcDayFromRange() {
    if (this.dayTouched || !this.asked) return;
    const today = isoDate(serviceToday());
    const ask = this.asked;
    this.fcDay.value = ask.start === ask.end && ask.start < today ? ask.start : isoDate(addDays(serviceToday(), -1));
  }

  /** A forecast record from the topic or a reply. Within one forecast a record that is behind
   *  the one shown (a reply overtaken by the topic's updates) is dropped; a snapshot is the
   *  server's word (null: it knows of none, e.g. after a restart, and a running one is gone). */
  _fcApply(rec, { snapshot = false } = {}) {
    if (rec === null || rec === undefined) {
      if (snapshot && this.forecast && this.forecast.state === "running") this.forecast = null;
      this._fcRender();
      return;
    }
    const cur = this.forecast;
    if (!snapshot && cur && cur.id === rec.id && fcStep(rec) < fcStep(cur)) return;
    this.forecast = rec;
    this._fcRender();
  }

  async _fcStartRun() {
    const day = this.fcDay.value;
    const robots = this.fcPicks.filter((p) => p.box.checked).map((p) => p.n);
    if (!/^\d{4}-\d{2}-\d{2}$/.test(day)) return this._fcSay(t("stats.fc.noDay"), true);
    if (!robots.length) return this._fcSay(t("stats.fc.noFleet"), true);
    this.fcStarting = true;
    this._fcSay(t("stats.fc.starting"));
    this._fcRender();
    try {
      const reply = await this.conn.request(
        { clientmsg: "stats", action: "forecast", day, robots, policy: "serveur", utc_offset: offsetText(offsetAt(day)) },
        { timeout: STATS_TIMEOUT_MS },
      );
      this.fcError = "";
      this._fcApply(reply.forecast);
    } catch (err) {
      if (err && err.code === "not_found") this.fcError = t("stats.fc.noDishes", { day: dateWords(day) });
      else if (err && err.code === "conflict") this.fcError = t("stats.fc.busy");
      else {
        showError(err);
        this.fcError = t("stats.fc.startFailed");
      }
    } finally {
      this.fcStarting = false;
      this._fcRender();
    }
  }

  async _fcCancelRun() {
    this.fcCancel.disabled = true;
    try {
      const reply = await this.conn.request({ clientmsg: "stats", action: "forecast_cancel" });
      this._fcApply(reply.forecast);
    } catch (err) {
      if (!err || err.code !== "not_found") showError(err); // not_found: it had just ended
    } finally {
      this.fcCancel.disabled = false;
      this._fcRender();
    }
  }

  /** The forecast section's line: what is happening, or why Start was refused. */
  _fcSay(text, error = false) {
    this.fcError = error ? text : "";
    this.fcMessage.textContent = text;
    this.fcMessage.classList.toggle("error", error);
  }

  _fcRender() {
    const fc = this.forecast;
    const running = Boolean(fc && fc.state === "running");
    this.fcStart.disabled = running || this.fcStarting;
    this.fcCancel.hidden = !running;
    if (this.fcError) this._fcSay(this.fcError, true);
    else if (this.fcStarting) this._fcSay(t("stats.fc.starting"));
    else this._fcSay(fc ? fcStateText(fc) : "");
    this.fcResult.hidden = !fc;
    if (!fc) return;
    const current = this._fleetNow();
    this.fcHeading.textContent = t("stats.fc.heading", { day: dateWords(fc.day), count: fc.dishes });
    // Each fleet's step while it runs; after, only if one did not finish.
    const unfinished = fc.fleets.some((f) => f.state !== "done");
    this.fcProgress.hidden = !running && !unfinished;
    this.fcProgress.replaceChildren(
      ...fc.fleets.map((f) =>
        el(
          "li",
          { class: `fc-step fc-${f.state}`, "data-robots": f.robots },
          t("stats.fc.progressItem", { fleet: t("stats.fc.fleet", { count: f.robots }), state: FLEET_PROGRESS[f.state] ? t(FLEET_PROGRESS[f.state]) : f.state }),
        ),
      ),
    );
    const done = fc.fleets.filter((f) => f.state === "done");
    this.fcSentences.hidden = !done.length;
    this.fcSentences.replaceChildren(
      ...done.map((f) => {
        let text = t("stats.fc.sentence", { count: f.robots, p95: minutes(f.wait_p95), mean: minutes(f.wait_mean) });
        if (f.undelivered) text += ` ${t("stats.fc.undelivered", { count: f.undelivered })}`;
        return el("li", { "data-robots": f.robots }, text);
      }),
    );
    const head = ["stats.fc.col.robots", "stats.fc.col.delivered", "stats.fc.col.waitMean", "stats.fc.col.waitP95"];
    this.fcTable.replaceChildren(
      el(
        "table",
        { class: "stats-table fc-table" },
        el("caption", { "data-i18n": "stats.fc.caption" }),
        el("thead", {}, el("tr", {}, ...head.map((k) => el("th", { scope: "col", "data-i18n": k })))),
        el(
          "tbody",
          {},
          ...fc.fleets.map((f) => {
            const ok = f.state === "done";
            const delivered = ok ? t("stats.fc.deliveredOf", { delivered: count(f.delivered), dishes: count(fc.dishes) }) : DASH;
            return el(
              "tr",
              { class: f.robots === current ? "now" : null, "data-robots": f.robots },
              el("th", { scope: "row" }, el("span", { class: "fc-fleet-name" }, t("stats.fc.fleet", { count: f.robots })), f.robots === current ? [" ", el("span", { class: "fc-now" }, t("stats.fc.now"))] : null),
              el("td", { "data-col": "delivered" }, delivered),
              el("td", { "data-col": "wait-mean" }, ok ? minutes(f.wait_mean) : DASH),
              el("td", { "data-col": "wait-p95" }, ok ? minutes(f.wait_p95) : DASH),
            );
          }),
        ),
      ),
    );
    this._fcChart();
  }

  _fcChart() {
    const fc = this.forecast;
    if (!fc || this.fcResult.hidden) return;
    const width = Math.min(560, this.fcChart.clientWidth || 320);
    this.fcDrawnWidth = this.fcChart.clientWidth;
    const done = fc.fleets.filter((f) => f.state === "done" && f.wait_p95 !== null);
    const list = new Intl.ListFormat(locale(), { type: "unit", style: "short" });
    const label = done.length
      ? t("stats.fc.chartSummary", { list: list.format(done.map((f) => t("stats.fc.chartItem", { count: f.robots, wait: minutes(f.wait_p95) }))) })
      : t("stats.fc.chartNone");
    this.fcChart.replaceChildren(fleetChart({ fleets: fc.fleets, current: this._fleetNow(), width, label }));
  }

  _download(which) {
    if (!this.figures || !this.asked) return;
    const ask = this.asked;
    const text = which === "figures" ? figuresCsv(this.figures, ask.offset) : tripsCsv(this.trips, ask.offset);
    const span_ = ask.start === ask.end ? ask.start : `${ask.start}_${ask.end}`;
    const name = which === "figures" ? `serveur-figures-${ask.by}-${span_}.csv` : `serveur-trips-${span_}.csv`;
    const url = URL.createObjectURL(new Blob([text], { type: "text/csv;charset=utf-8" }));
    const link = el("a", { href: url, download: name, hidden: true });
    document.body.append(link);
    link.click();
    link.remove();
    setTimeout(() => URL.revokeObjectURL(url), 10_000);
  }
}
