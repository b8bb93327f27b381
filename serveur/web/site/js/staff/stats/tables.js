// The Statistics tab's figures as text: the range's headline tiles, the table of periods (the
// charts' text alternative) and each robot's share of the work. Pure builders (figures in, nodes
// out), apart from the panel that places them; `tableHead` is the forecast's too.

import { el } from "../../ui.js";
import { t } from "../../i18n.js";
import { count, distance, duration, minutes, one, percent, span } from "./format.js";

/** A table's head: a column header per catalog key. */
export function tableHead(keys) {
  return el("thead", {}, el("tr", {}, ...keys.map((k) => el("th", { scope: "col", "data-i18n": k }))));
}

/** A table's row: its header cell, then a cell per value. */
function bodyRow(attrs, head, values) {
  return el("tr", attrs, el("th", { scope: "row" }, head), ...values.map((v) => el("td", {}, v)));
}

/** The range's headline figures, a tile each (a term and its value). */
export function tiles(total) {
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
  return groups.map((g) => el("div", { class: "tile" }, ...g));
}

/** A row per period (`labels`: their names), then the total. */
export function periodsTable(doc, labels) {
  const head = ["stats.col.period", "stats.col.delivered", "stats.col.waitMean", "stats.col.waitP95", "stats.col.pass", "stats.col.trips", "stats.col.returned", "stats.col.busy"];
  const row = (label, p, isTotal) =>
    bodyRow({ class: isTotal ? "total" : null }, label, [
      count(p.delivered),
      minutes(p.wait_mean),
      minutes(p.wait_p95),
      duration(p.pass_mean),
      count(p.trips),
      count(p.returned),
      percent(p.busy_share),
    ]);
  return el(
    "table",
    { class: "stats-table" },
    el("caption", { "data-i18n": "stats.table.caption" }),
    tableHead(head),
    el("tbody", {}, ...doc.periods.map((p, i) => row(labels[i], p, false)), row(t("stats.total"), doc.total, true)),
  );
}

/** Each robot's trips, busy share and time, distance, errors and dropped links. */
export function robotsTable(total) {
  if (!total.robots.length) return el("p", { class: "muted", "data-i18n": "stats.robots.none" });
  const head = ["stats.col.robot", "stats.col.trips", "stats.col.busyShare", "stats.col.busyTime", "stats.col.distance", "stats.col.errors", "stats.col.linkDrops"];
  return el(
    "table",
    { class: "stats-table stats-robots" },
    el("caption", { class: "visually-hidden", "data-i18n": "stats.robots.title" }),
    tableHead(head),
    el(
      "tbody",
      {},
      ...total.robots.map((r) =>
        bodyRow({}, r.robot, [count(r.trips), percent(r.busy_share), span(r.busy_s), distance(r.distance_m), count(r.errors), count(r.link_drops)]),
      ),
    ),
  );
}

/** Guests' calls per kind (how many, answered within: half of them, nine in ten), then what was
 *  escalated or cancelled and the bussing trips (from a plates call to the robot at the table). */
export function callsTable(total) {
  if (!total.calls && !total.bussing_trips) return el("p", { class: "muted", "data-i18n": "stats.calls.none" });
  const head = ["stats.col.call", "stats.col.calls", "stats.col.answerP50", "stats.col.answerP90"];
  const words = { plates: "stats.calls.kind.plates", waiter: "stats.calls.kind.waiter", bill: "stats.calls.kind.bill" };
  const kinds = Object.entries(words).map(([k, key]) =>
    bodyRow({}, t(key), [count(total[`calls_${k}`]), duration(total[`answer_p50_${k}`]), duration(total[`answer_p90_${k}`])]),
  );
  const all = bodyRow({ class: "total" }, t("stats.total"), [count(total.calls), duration(total.answer_p50), duration(total.answer_p90)]);
  return el(
    "div",
    {},
    el(
      "table",
      { class: "stats-table stats-calls" },
      el("caption", { class: "visually-hidden", "data-i18n": "stats.calls.title" }),
      tableHead(head),
      el("tbody", {}, ...kinds, all),
    ),
    el("p", { "data-testid": "stats-calls-more" }, t("stats.calls.more", {
      escalated: count(total.calls_escalated),
      cancelled: count(total.calls_cancelled),
      trips: count(total.bussing_trips),
      p50: duration(total.call_to_robot_p50),
      p90: duration(total.call_to_robot_p90),
    })),
  );
}
