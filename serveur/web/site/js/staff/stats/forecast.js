// The Statistics tab's "How many robots do I need?": a past service day's dishes replayed by the
// server (`stats` `forecast`: a `serveur replay` child per fleet size, one after the other) with
// the fleet sizes ticked; each fleet's step and result arrive on the `forecast` topic, shown as
// words, a table and a bar chart of the 95 % wait, the fleet the site has now marked. Its own
// module: it has its own form, its own state and its own topic, apart from the figures above it.

import { el, showError } from "../../ui.js";
import { t } from "../../i18n.js";
import { fleetChart } from "./charts.js";
import { addDays, count, DASH, dateWords, fmt, isoDate, locale, minutes, offsetAt, offsetText, serviceToday } from "./format.js";
import { tableHead } from "./tables.js";

const STATS_TIMEOUT_MS = 130_000; // the server gives a computation up to 120 s
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

export class ForecastSection {
  /** `id(name)`: a page-unique element id (the panel's). */
  constructor(conn, live, id) {
    this.conn = conn;
    this.live = live;
    this.record = null; // the latest forecast record (the `forecast` topic's), or null
    this.error = ""; // why the last Start was refused, shown until the next one
    this.starting = false;
    this.fleetsTouched = false; // the owner chose the fleet sizes: no more defaults
    this.dayTouched = false; // the owner chose the day: the range no longer sets it
    this.drawnWidth = 0; // the chart's box width when it was last drawn
    const today = isoDate(serviceToday());
    this.day = el("input", { id: id("fc-day"), name: "forecast-day", type: "date", value: isoDate(addDays(serviceToday(), -1)), max: today, required: true });
    this.day.addEventListener("input", () => {
      this.dayTouched = true;
    });
    this.picks = FLEET_SIZES.map((n) => {
      const box = el("input", { type: "checkbox", name: "forecast-robots", value: n, id: id(`fc-robots-${n}`) });
      box.addEventListener("change", () => {
        this.fleetsTouched = true;
      });
      const now = el("span", { class: "fc-now", hidden: true, "data-i18n": "stats.fc.now" });
      return { n, box, now, label: el("label", { class: "fc-pick", for: box.id }, box, el("span", { class: "fc-pick-face" }, el("span", { class: "fc-pick-n" }, fmt(n)), now)) };
    });
    const fleetsLegend = id("fc-fleets");
    this.startBtn = el("button", { type: "submit", class: "primary", "data-needs-online": true, "data-i18n": "stats.fc.start" });
    this.cancelBtn = el("button", { type: "button", class: "secondary", hidden: true, "data-needs-online": true, "data-i18n": "stats.fc.cancel", onclick: () => this._cancelRun() });
    this.form = el(
      "form",
      { class: "fc-controls", "data-i18n-aria-label": "stats.fc.controls" },
      el("div", { class: "stats-field" }, el("label", { for: this.day.id, "data-i18n": "stats.fc.day" }), this.day),
      el("fieldset", { class: "fc-fleets" }, el("legend", { id: fleetsLegend, "data-i18n": "stats.fc.fleets" }), el("div", { class: "fc-picks" }, ...this.picks.map((p) => p.label))),
      el("div", { class: "form-buttons fc-buttons" }, this.startBtn, this.cancelBtn),
    );
    this.form.addEventListener("submit", (e) => {
      e.preventDefault();
      this._startRun();
    });
    this.message = el("p", { class: "fc-message", role: "status", "aria-live": "polite" });
    this.heading = el("h3", { class: "fc-heading" });
    this.progress = el("ol", { class: "fc-progress" });
    this.sentences = el("ul", { class: "fc-sentences" });
    this.table = el("div", { class: "table-scroll", tabindex: "0", role: "region", "data-i18n-aria-label": "stats.fc.caption" });
    this.chartBox = el("div", { class: "chart-box fc-chart" });
    const chartTitle = id("fc-chart-title");
    this.result = el(
      "div",
      { class: "fc-result", hidden: true },
      this.heading,
      this.progress,
      this.sentences,
      el("div", { class: "fc-side" }, this.table, el("div", { class: "fc-chart-wrap" }, el("h4", { id: chartTitle, "data-i18n": "stats.fc.chart" }), this.chartBox)),
    );
    const title = id("fc-title");
    this.section = el(
      "section",
      { class: "card stats-forecast", "aria-labelledby": title },
      el("h2", { id: title, "data-i18n": "stats.fc.title" }),
      el("p", { class: "muted fc-explain", "data-i18n": "stats.fc.explain" }),
      this.form,
      this.message,
      this.result,
    );
    conn.addEventListener("snapshot", (e) => {
      const data = e.detail.data || {};
      if ("forecast" in data) this._apply(data.forecast, { snapshot: true });
    });
    conn.addEventListener("update", (e) => {
      if (e.detail.topic === "forecast") this._apply(e.detail.data);
    });
    if (live) {
      live.addEventListener("change", (e) => {
        if (e.detail.topic === "robots") this._defaults();
      });
    }
    this._defaults();
  }

  /** Once the section is on the page: its chart is drawn again to its width. */
  observe() {
    new ResizeObserver(() => {
      const w = this.chartBox.clientWidth;
      if (this.record && w && Math.abs(w - this.drawnWidth) > 8) this.chart();
    }).observe(this.chartBox);
  }

  /** The tab was opened: `today` is the latest day; the forecast under way or the last one
   *  (this console's or another owner's): its record now and each change, kept across
   *  reconnections (the owner's alone: scope stats). */
  opened(today) {
    this.day.max = today; // the console may have stayed open overnight
    this.conn.subscribe(["forecast"]);
  }

  /** The robots the site has now (registered, whatever their state): the fleet to compare. */
  _fleetNow() {
    return this.live && this.live.robots ? this.live.robots.size : 0;
  }

  /** Until the owner picks: the fleet now −1, the same, +1 and +2 (within 1..6); the current
   *  size marked "now" on its box. */
  _defaults() {
    const current = this._fleetNow();
    const wanted = new Set([current - 1, current, current + 1, current + 2]);
    for (const p of this.picks) {
      if (!this.fleetsTouched) p.box.checked = wanted.has(p.n);
      p.now.hidden = p.n !== current;
    }
    if (this.record) this.render();
  }

  /** The day to replay follows the range `asked` while it is one past day; else yesterday. */
  dayFromRange(asked) {
    if (this.dayTouched || !asked) return;
    const today = isoDate(serviceToday());
    this.day.value = asked.start === asked.end && asked.start < today ? asked.start : isoDate(addDays(serviceToday(), -1));
  }

  /** A forecast record from the topic or a reply. Within one forecast a record that is behind
   *  the one shown (a reply overtaken by the topic's updates) is dropped; a snapshot is the
   *  server's word (null: it knows of none, e.g. after a restart, and a running one is gone). */
  _apply(rec, { snapshot = false } = {}) {
    if (rec === null || rec === undefined) {
      if (snapshot && this.record && this.record.state === "running") this.record = null;
      this.render();
      return;
    }
    const cur = this.record;
    if (!snapshot && cur && cur.id === rec.id && fcStep(rec) < fcStep(cur)) return;
    this.record = rec;
    this.render();
  }

  async _startRun() {
    const day = this.day.value;
    const robots = this.picks.filter((p) => p.box.checked).map((p) => p.n);
    if (!/^\d{4}-\d{2}-\d{2}$/.test(day)) return this._say(t("stats.fc.noDay"), true);
    if (!robots.length) return this._say(t("stats.fc.noFleet"), true);
    this.starting = true;
    this._say(t("stats.fc.starting"));
    this.render();
    try {
      const reply = await this.conn.request(
        { clientmsg: "stats", action: "forecast", day, robots, policy: "serveur", utc_offset: offsetText(offsetAt(day)) },
        { timeout: STATS_TIMEOUT_MS },
      );
      this.error = "";
      this._apply(reply.forecast);
    } catch (err) {
      if (err && err.code === "not_found") this.error = t("stats.fc.noDishes", { day: dateWords(day) });
      else if (err && err.code === "conflict") this.error = t("stats.fc.busy");
      else {
        showError(err);
        this.error = t("stats.fc.startFailed");
      }
    } finally {
      this.starting = false;
      this.render();
    }
  }

  async _cancelRun() {
    this.cancelBtn.disabled = true;
    try {
      const reply = await this.conn.request({ clientmsg: "stats", action: "forecast_cancel" });
      this._apply(reply.forecast);
    } catch (err) {
      if (!err || err.code !== "not_found") showError(err); // not_found: it had just ended
    } finally {
      this.cancelBtn.disabled = false;
      this.render();
    }
  }

  /** The forecast section's line: what is happening, or why Start was refused. */
  _say(text, error = false) {
    this.error = error ? text : "";
    this.message.textContent = text;
    this.message.classList.toggle("error", error);
  }

  render() {
    const fc = this.record;
    const running = Boolean(fc && fc.state === "running");
    this.startBtn.disabled = running || this.starting;
    this.cancelBtn.hidden = !running;
    if (this.error) this._say(this.error, true);
    else if (this.starting) this._say(t("stats.fc.starting"));
    else this._say(fc ? fcStateText(fc) : "");
    this.result.hidden = !fc;
    if (!fc) return;
    const current = this._fleetNow();
    this.heading.textContent = t("stats.fc.heading", { day: dateWords(fc.day), count: fc.dishes });
    // Each fleet's step while it runs; after, only if one did not finish.
    const unfinished = fc.fleets.some((f) => f.state !== "done");
    this.progress.hidden = !running && !unfinished;
    this.progress.replaceChildren(
      ...fc.fleets.map((f) =>
        el(
          "li",
          { class: `fc-step fc-${f.state}`, "data-robots": f.robots },
          t("stats.fc.progressItem", { fleet: t("stats.fc.fleet", { count: f.robots }), state: FLEET_PROGRESS[f.state] ? t(FLEET_PROGRESS[f.state]) : f.state }),
        ),
      ),
    );
    const done = fc.fleets.filter((f) => f.state === "done");
    this.sentences.hidden = !done.length;
    this.sentences.replaceChildren(
      ...done.map((f) => {
        let text = t("stats.fc.sentence", { count: f.robots, p95: minutes(f.wait_p95), mean: minutes(f.wait_mean) });
        if (f.undelivered) text += ` ${t("stats.fc.undelivered", { count: f.undelivered })}`;
        return el("li", { "data-robots": f.robots }, text);
      }),
    );
    const head = ["stats.fc.col.robots", "stats.fc.col.delivered", "stats.fc.col.waitMean", "stats.fc.col.waitP95"];
    this.table.replaceChildren(
      el(
        "table",
        { class: "stats-table fc-table" },
        el("caption", { "data-i18n": "stats.fc.caption" }),
        tableHead(head),
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
    this.chart();
  }

  /** The bar chart of the 95 % wait per fleet size, drawn to the box's width. */
  chart() {
    const fc = this.record;
    if (!fc || this.result.hidden) return;
    const width = Math.min(560, this.chartBox.clientWidth || 320);
    this.drawnWidth = this.chartBox.clientWidth;
    const done = fc.fleets.filter((f) => f.state === "done" && f.wait_p95 !== null);
    const list = new Intl.ListFormat(locale(), { type: "unit", style: "short" });
    const label = done.length
      ? t("stats.fc.chartSummary", { list: list.format(done.map((f) => t("stats.fc.chartItem", { count: f.robots, wait: minutes(f.wait_p95) }))) })
      : t("stats.fc.chartNone");
    this.chartBox.replaceChildren(fleetChart({ fleets: fc.fleets, current: this._fleetNow(), width, label }));
  }
}
