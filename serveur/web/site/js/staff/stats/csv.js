// The Statistics tab's CSV files, built here byte for byte as `serveur stats --csv` writes them
// (serveur/stats/cli.py: figure_rows, trip_rows): the figures a row per period, the trip history
// a row per stop, numbers rounded as Python does. Its own module so that the CSV's exactness is
// in one place, apart from what the panel shows.

import { el } from "../../ui.js";
import { csvTime } from "./format.js";

// The CSV's columns, as serveur/stats/cli.py writes them (figure_rows, trip_rows).
const FIELDS = [
  "delivered", "wait_mean", "wait_p50", "wait_p95", "wait_max", "pass_mean", "pass_p95",
  "pass_max", "loading_s", "loading_per_trip", "trips", "trips_cancelled", "tables_per_trip",
  "dishes_per_trip", "returned", "resent", "voided", "table_timeouts", "staff_skips",
  "busy_share", "errors", "link_drops", "distance_m",
  // Guests' calls and bussing trips (issue 32).
  "calls", "calls_plates", "calls_waiter", "calls_bill", "calls_escalated", "calls_cancelled",
  "answer_p50", "answer_p90", "answer_p50_plates", "answer_p90_plates", "answer_p50_waiter",
  "answer_p90_waiter", "answer_p50_bill", "answer_p90_bill", "bussing_trips",
  "bussing_cancelled", "call_to_robot_p50", "call_to_robot_p90",
];
const ROBOT_FIELDS = ["busy_s", "busy_share", "loading_s", "trips", "errors", "distance_m"];
// Counts are whole numbers in the command's CSV; every other figure is a float ("15.0").
const COUNTS = new Set([
  "delivered", "trips", "trips_cancelled", "returned", "resent", "voided", "table_timeouts",
  "staff_skips", "errors", "link_drops", "calls", "calls_plates", "calls_waiter", "calls_bill",
  "calls_escalated", "calls_cancelled", "bussing_trips", "bussing_cancelled",
]);
const TRIP_COLUMNS = [
  "trip", "kind", "robot", "status", "created", "started", "left_pass", "ended", "loading_s",
  "stop", "table", "purpose", "arrived", "stop_ended", "outcome", "reason", "by", "at_table_s",
  "dishes",
];

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
        trip.kind,
        trip.robot || "",
        trip.status,
        csvTime(trip.created, offset),
        csvTime(trip.started, offset),
        csvTime(trip.left, offset),
        csvTime(trip.ended, offset),
        csvNumber(trip.loading_s, false),
        i + 1,
        s.table,
        s.purpose,
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

/** The file `name` holding `text`, downloaded by the browser. */
export function saveCsv(name, text) {
  const url = URL.createObjectURL(new Blob([text], { type: "text/csv;charset=utf-8" }));
  const link = el("a", { href: url, download: name, hidden: true });
  document.body.append(link);
  link.click();
  link.remove();
  setTimeout(() => URL.revokeObjectURL(url), 10_000);
}
