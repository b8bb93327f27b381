// Statistics (the owner's): how past services went, from the server's records, through the
// protocol's `stats` verb (the very figures `serveur stats` prints: docs/statistics.md).
//
// A range (today, yesterday, the last 7 days, or from one date to another: service days, which
// start at 04:00) grouped by hour or by day; the range's headline figures; two charts drawn as
// inline SVG (dishes delivered, and the wait within which 95 % of dishes were served, per
// period), each with a text alternative (an aria-label summary, and the figures as a table);
// each robot's share of the work; the trip history, each trip opening onto its stops and
// dishes; both as CSV files, with the columns `serveur stats --csv` writes; and "How many robots
// do I need?", a past day replayed with other fleet sizes.
//
// This module is the panel: the range picker, what was found and where it goes. The parts live
// in stats/: format.js (numbers, dates, times), tables.js (tiles and tables), charts.js (the
// SVG), trips.js (the trip history), csv.js (the files), forecast.js (the forecast section).
//
// Times are shown on the restaurant's clock as this device knows it: the request names this
// device's UTC offset, and every time is written with that same offset, so the periods, the
// times and the CSV agree with `serveur stats --utc-offset` on the server.

import { el, showError } from "../ui.js";
import { onLangChange, t } from "../i18n.js";
import { chart } from "./stats/charts.js";
import { figuresCsv, saveCsv, tripsCsv } from "./stats/csv.js";
import { ForecastSection } from "./stats/forecast.js";
import { addDays, count, dateWords, isoDate, minutes, offsetAt, offsetText, periodWords, serviceToday } from "./stats/format.js";
import { callsTable, periodsTable, robotsTable, tiles } from "./stats/tables.js";
import { TripHistory } from "./stats/trips.js";

export { figuresCsv, tripsCsv } from "./stats/csv.js";

const RELOAD_AFTER_MS = 60_000; // the tab opened again later than this: the figures are fetched anew
const STATS_TIMEOUT_MS = 130_000; // the server gives a computation up to 120 s

const RANGES = [
  ["today", "stats.range.today"],
  ["yesterday", "stats.range.yesterday"],
  ["week", "stats.range.week"],
  ["custom", "stats.range.custom"],
];

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
    this.callTable = scroller("stats.calls.title");
    this.tripHistory = new TripHistory();
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
      el("section", { class: "card", "aria-labelledby": `${robotsTitle}-calls` }, el("h3", { id: `${robotsTitle}-calls`, "data-i18n": "stats.calls.title" }), this.callTable),
      el("section", { class: "card", "aria-labelledby": tripsTitle }, el("h3", { id: tripsTitle, "data-i18n": "stats.trips.title" }), el("p", { class: "muted", "data-i18n": "stats.trips.hint" }), this.tripHistory.note, this.tripHistory.list, el("div", { class: "form-buttons stats-more" }, this.tripHistory.more)),
    );
    // -- "How many robots do I need?": a recorded day replayed with other fleet sizes
    this.forecast = new ForecastSection(conn, live, id);

    root.append(el("div", { class: "stats-wrap" }, this.form, this.state, this.results, this.forecast.section));

    this.drawnWidth = 0;
    new ResizeObserver(() => {
      const w = this.deliveredChart.clientWidth;
      if (this.figures && w && Math.abs(w - this.drawnWidth) > 8) this._charts();
    }).observe(this.deliveredChart);
    this.forecast.observe();
    onLangChange(() => {
      this._render();
      this.forecast.render();
    });
    this._render();
  }

  /** The tab was opened: fetch the figures the first time, and again when they may be old. */
  shown() {
    const today = isoDate(serviceToday());
    this.from.max = this.to.max = today; // the console may have stayed open overnight
    this.forecast.opened(today);
    if (!this.figures || Date.now() - this.loadedAt > RELOAD_AFTER_MS) this.load();
    else this._charts(); // the tab was hidden: the charts are drawn to its width again
    this.forecast.chart();
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
        this.tripHistory.reset(); // another range: its latest trips first
      }
      this.asked = ask;
      this.forecast.dayFromRange(ask);
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
    this.tiles.replaceChildren(...tiles(doc.total));
    this._charts();
    this.periodTable.replaceChildren(periodsTable(doc, this._labels()));
    this.robotTable.replaceChildren(robotsTable(doc.total));
    this.callTable.replaceChildren(callsTable(doc.total));
    this.tripHistory.render(this.trips, this.asked.offset);
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

  _download(which) {
    if (!this.figures || !this.asked) return;
    const ask = this.asked;
    const text = which === "figures" ? figuresCsv(this.figures, ask.offset) : tripsCsv(this.trips, ask.offset);
    const span_ = ask.start === ask.end ? ask.start : `${ask.start}_${ask.end}`;
    const name = which === "figures" ? `serveur-figures-${ask.by}-${span_}.csv` : `serveur-trips-${span_}.csv`;
    saveCsv(name, text);
  }
}
