// The Statistics tab's "How many robots do I need?": a past service day's dishes replayed by the
// server (`stats` `forecast`: a `serveur replay` child per fleet size, one after the other) with
// the fleet sizes ticked; each fleet's step and result arrive on the `forecast` topic, shown as
// words, a table and a bar chart of the 95 % wait, the fleet the site has now marked. Its own
// module: it has its own form, its own state and its own topic, apart from the figures above it.
//
// The day offered is the last one the restaurant had a service (`stats` `last_service`: the
// day before is often a day it was closed); with none yet, it says so and offers no Start. Once
// fleets are replayed, one sentence recommends the smallest fleet that meets the site's target
// wait (the `target_wait` setting; the rule is `recommend`, pure), and a note compares the
// replay with what that day's record says (`stats` `figures` for the day) and says why they
// differ: what the replay simulates instead of the day's people and robots (`REPLAY_MODEL`).

import { el, showError } from "../../ui.js";
import { t } from "../../i18n.js";
import { fleetChart } from "./charts.js";
import { addDays, count, DASH, dateWords, duration, fmt, isoDate, locale, minutes, offsetAt, offsetText, serviceToday } from "./format.js";
import { tableHead } from "./tables.js";

const STATS_TIMEOUT_MS = 130_000; // the server gives a computation up to 120 s
const FLEET_SIZES = [1, 2, 3, 4, 5, 6]; // the fleet sizes an owner may try in a forecast
const TARGET_WAIT = 600; // the server's target wait until the owner sets one (s)
// Two 95 % waits closer than this are the same: which robot happens to be free first moves a
// replay's waits by seconds, and a guest does not tell half a minute apart.
export const SAME_WAIT_S = 30;
// What the replay simulates instead of the day's people and robots: serveur/replay/model.py's
// ReplayOptions defaults and dish_dwell, which a forecast does not change (seconds; guests
// mostly take dwellMin..dwellMax, a few up to dwellLongest; awayPer100 parties are away).
// tests/replay/test_forecast_words.py checks these against the replay's own numbers.
export const REPLAY_MODEL = { loadFixed: 10, loadPerPlate: 4, dwellMin: 6, dwellMax: 20, dwellLongest: 40, awayPer100: 3 };
// A forecast's fleet states, in the order they go through (a record never goes back).
const FLEET_STEP = { waiting: 0, running: 1, done: 2, failed: 2, cancelled: 2 };
const FLEET_PROGRESS = {
  waiting: "stats.fc.progress.waiting",
  running: "stats.fc.progress.running",
  done: "stats.fc.progress.done",
  failed: "stats.fc.progress.failed",
  cancelled: "stats.fc.progress.cancelled",
};

/** Set a node's text only when it changed (a screen reader is not told the same words again). */
function setText(node, text) {
  if (node.textContent !== text) node.textContent = text;
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

/**
 * The fleets replayed, judged against the target wait (s): which fleet to recommend. Pure.
 *
 * A fleet meets the target when it delivered every dish and 95 % within the target. The
 * smallest that does is recommended (`enough: true`), with: `faster`, the larger fleet tried
 * that is fastest by more than SAME_WAIT_S (null: none is, or `tried` larger is false: none was
 * tried); `untried`, the fleet just below it when that one was not tried and might also do
 * (null otherwise). When none meets it (`enough: false`): the largest fleet tried (`robots`,
 * `p95`, `undelivered`), and `plateau`, the smallest fleet no larger one beats by more than
 * SAME_WAIT_S (more robots do not make it faster from there; null when that is the largest
 * one tried: more might). Null when no fleet has finished.
 */
export function recommend(fleets, target) {
  const done = fleets.filter((f) => f.state === "done" && typeof f.wait_p95 === "number").sort((a, b) => a.robots - b.robots);
  if (!done.length || !(target > 0)) return null;
  const meets = (f) => !f.undelivered && f.wait_p95 <= target;
  const beats = (f, g) => !f.undelivered && f.wait_p95 < g.wait_p95 - SAME_WAIT_S;
  const pick = done.find(meets);
  if (pick) {
    const larger = done.filter((f) => f.robots > pick.robots);
    const quicker = larger.filter((f) => beats(f, pick));
    const best = quicker.reduce((a, f) => (a === null || f.wait_p95 < a.wait_p95 - SAME_WAIT_S ? f : a), null);
    const below = done.filter((f) => f.robots < pick.robots); // all of them miss the target
    const highestMiss = below.length ? below[below.length - 1].robots : 0;
    return {
      enough: true,
      robots: pick.robots,
      p95: pick.wait_p95,
      tried: larger.length > 0,
      faster: best && { robots: best.robots, p95: best.wait_p95 },
      untried: pick.robots - 1 > highestMiss ? pick.robots - 1 : null,
    };
  }
  const last = done[done.length - 1];
  const plateau = done.find((f) => !f.undelivered && !done.some((g) => g.robots > f.robots && beats(g, f)));
  return {
    enough: false,
    robots: last.robots,
    p95: last.wait_p95,
    undelivered: last.undelivered || 0,
    plateau: plateau && plateau.robots < last.robots ? plateau.robots : null,
  };
}

/** `recommend`'s verdict as the sentence the owner reads. */
export function adviceText(rec, target) {
  const goal = minutes(target);
  if (rec.enough) {
    const words = [t("stats.fc.advice.enough", { count: rec.robots, p95: minutes(rec.p95), target: goal })];
    if (rec.faster) words.push(t("stats.fc.advice.faster", { count: rec.faster.robots, p95: minutes(rec.faster.p95) }));
    else if (rec.tried) words.push(t("stats.fc.advice.noFaster"));
    if (rec.untried) words.push(t("stats.fc.advice.untried", { count: rec.untried }));
    return words.join(" ");
  }
  const words = [
    rec.undelivered
      ? t("stats.fc.advice.shortUndelivered", { count: rec.robots, target: goal })
      : t("stats.fc.advice.short", { count: rec.robots, p95: minutes(rec.p95), target: goal }),
  ];
  if (rec.plateau) words.push(t("stats.fc.advice.plateau", { count: rec.plateau }));
  return words.join(" ");
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
    // The last day with a service before today (`stats` `last_service`): undefined until the
    // server says, null when the restaurant has had none.
    this.lastService = undefined;
    this.askingSince = null; // the today a last_service request under way was sent for
    this.rangeDay = null; // the past day the figures above show, if they show one day
    // What the record says of the forecast's day (`stats` `figures`), read once per forecast:
    // {key} while it is read, then {key, total} or {key, failed}; key: "<forecast id>/<day>".
    this.recorded = null;
    const today = isoDate(serviceToday());
    this.day = el("input", { id: id("fc-day"), name: "forecast-day", type: "date", value: "", max: today, required: true });
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
    this.adviceWords = el("strong");
    this.advice = el("p", { class: "fc-advice", hidden: true }, this.adviceWords);
    this.progress = el("ol", { class: "fc-progress" });
    this.sentences = el("ul", { class: "fc-sentences" });
    this.table = el("div", { class: "table-scroll", tabindex: "0", role: "region", "data-i18n-aria-label": "stats.fc.caption" });
    this.chartBox = el("div", { class: "chart-box fc-chart" });
    const chartTitle = id("fc-chart-title");
    this.recordedLine = el("p", { class: "fc-recorded" });
    this.replayedLine = el("p", { class: "fc-replayed" });
    this.countsLine = el("p", { class: "fc-counts" });
    this.modelLine = el("p", { class: "muted fc-model" });
    this.passLine = el("p", { class: "fc-pass" });
    this.why = el(
      "div",
      { class: "fc-why", hidden: true },
      el("h4", { "data-i18n": "stats.fc.why.title" }),
      this.recordedLine,
      this.replayedLine,
      this.countsLine,
      this.modelLine,
      this.passLine,
    );
    this.result = el(
      "div",
      { class: "fc-result", hidden: true },
      this.heading,
      this.advice,
      this.progress,
      this.sentences,
      el("div", { class: "fc-side" }, this.table, el("div", { class: "fc-chart-wrap" }, el("h4", { id: chartTitle, "data-i18n": "stats.fc.chart" }), this.chartBox)),
      this.why,
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
        if (e.detail.topic === "settings" && this.record) this.render(); // the target changed
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
    this.conn.subscribe(["forecast", "settings"]); // settings: the target wait
    this._askLastService(today);
  }

  /** Ask the server which day last had a service before `today` (a new service may have been
   *  recorded since the tab was last opened); the day offered follows it until the owner picks. */
  async _askLastService(today) {
    if (this.askingSince === today) return;
    this.askingSince = today;
    try {
      const reply = await this.conn.request({ clientmsg: "stats", action: "last_service", before: today, utc_offset: offsetText(offsetAt(today)) }, { resend: true });
      this.lastService = reply.last_service ?? null;
    } catch (err) {
      showError(err);
    } finally {
      if (this.askingSince === today) this.askingSince = null;
    }
    this._offerDay();
    this.render();
  }

  /** The day offered until the owner picks one: the past day the figures above show, else the
   *  last day with a service (yesterday while the server has not said; none if it had none). */
  _offerDay() {
    if (this.dayTouched) return;
    const yesterday = isoDate(addDays(serviceToday(), -1));
    this.day.value = this.rangeDay || (this.lastService === undefined ? yesterday : this.lastService || "");
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

  /** The day to replay follows the range `asked` while it is one past day; else the last day
   *  with a service. */
  dayFromRange(asked) {
    if (!asked) return;
    const today = isoDate(serviceToday());
    this.rangeDay = asked.start === asked.end && asked.start < today ? asked.start : null;
    this._offerDay();
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
    // No service recorded yet, and no forecast of this server run: nothing to replay, no Start.
    const never = this.lastService === null && !fc;
    this.form.hidden = never;
    if (this.error) this._say(this.error, true);
    else if (this.starting) this._say(t("stats.fc.starting"));
    else if (never) this._say(t("stats.fc.noService"));
    else this._say(fc ? fcStateText(fc) : "");
    this.result.hidden = !fc;
    if (!fc) return;
    const current = this._fleetNow();
    this.heading.textContent = t("stats.fc.heading", { day: dateWords(fc.day), count: fc.dishes });
    // The recommendation, once every fleet asked for has ended; with the site's target known.
    const target = this.live && this.live.settings ? (this.live.settings.target_wait ?? TARGET_WAIT) : null;
    const rec = running || target === null ? null : recommend(fc.fleets, target);
    setText(this.adviceWords, rec ? adviceText(rec, target) : "");
    this.advice.hidden = !rec;
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
    this._why(fc, done);
  }

  /** What the day's record says beside the replay, and why they differ. */
  _why(fc, done) {
    this.why.hidden = !done.length;
    if (!done.length) return;
    const key = `${fc.id}/${fc.day}`;
    if (!this.recorded || this.recorded.key !== key) this._readRecord(fc, key);
    const rec = this.recorded;
    const total = rec.total || null;
    let recorded = "";
    let same = null; // the replayed fleet the size of the day's own
    if (rec.failed) recorded = t("stats.fc.why.unread");
    else if (!total) recorded = t("stats.fc.why.reading");
    else if (!total.delivered) recorded = t("stats.fc.why.none", { day: dateWords(fc.day) });
    else {
      const robots = total.robots.filter((r) => r.trips > 0).length;
      const figures = { count: total.delivered, mean: minutes(total.wait_mean), p95: minutes(total.wait_p95) };
      recorded = robots ? t("stats.fc.why.recorded", { ...figures, robots: t("stats.fc.fleet", { count: robots }) }) : t("stats.fc.why.recordedNoRobot", figures);
      same = done.find((f) => f.robots === robots) || null;
    }
    setText(this.recordedLine, recorded);
    setText(this.replayedLine, same ? t("stats.fc.why.replayed", { count: same.robots, mean: minutes(same.wait_mean), p95: minutes(same.wait_p95) }) : "");
    this.replayedLine.hidden = !same;
    const counts = total && total.delivered && total.delivered !== fc.dishes;
    setText(this.countsLine, counts ? t("stats.fc.why.counts", { recorded: count(total.delivered), replayed: count(fc.dishes) }) : "");
    this.countsLine.hidden = !counts;
    const m = REPLAY_MODEL;
    setText(
      this.modelLine,
      t("stats.fc.why.model", {
        loadFixed: duration(m.loadFixed),
        loadPerPlate: duration(m.loadPerPlate),
        dwellMin: duration(m.dwellMin),
        dwellMax: duration(m.dwellMax),
        dwellLongest: duration(m.dwellLongest),
        away: fmt(m.awayPer100),
      }),
    );
    // Where the day's own time went that the replay simulates: the pass and the loading.
    const facts = [];
    if (total && total.delivered && total.pass_mean !== null) facts.push(t("stats.fc.why.pass", { pass: duration(total.pass_mean) }));
    if (total && total.trips && total.loading_per_trip !== null && total.dishes_per_trip !== null) {
      const assumed = duration(m.loadFixed + m.loadPerPlate * total.dishes_per_trip);
      facts.push(total.loading_per_trip > 0 ? t("stats.fc.why.loading", { loading: duration(total.loading_per_trip), assumed }) : t("stats.fc.why.noLoading", { assumed }));
    }
    setText(this.passLine, facts.join(" "));
    this.passLine.hidden = !facts.length;
  }

  /** Read the figures the record holds for the forecast's day (the same `stats` `figures` the
   *  tab above shows), once per forecast. */
  async _readRecord(fc, key) {
    this.recorded = { key };
    try {
      const reply = await this.conn.request(
        { clientmsg: "stats", action: "figures", by: "day", start: fc.day, end: fc.day, utc_offset: offsetText(offsetAt(fc.day)) },
        { resend: true, timeout: STATS_TIMEOUT_MS },
      );
      if (this.recorded.key === key) this.recorded = { key, total: reply.stats.total };
    } catch (err) {
      if (this.recorded.key === key) this.recorded = { key, failed: true };
      showError(err);
    }
    if (this.record && this.recorded.key === key) this.render();
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
