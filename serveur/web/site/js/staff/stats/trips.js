// The Statistics tab's trip history: the range's trips, newest first, a page at a time ("Show
// more"), each opening onto its facts, stops and dishes; the trips an owner opened stay open
// when the list is drawn again. Its own module so that the panel only says when and what.

import { el, KeyedList } from "../../ui.js";
import { lang, t } from "../../i18n.js";
import { clock, csvTime, DASH, dayName, duration } from "./format.js";

const TRIPS_PAGE = 50; // trips listed at first, and more at each "Show more"
const TRIP_STATUS = {
  queued: "stats.trip.queued",
  active: "stats.trip.active",
  done: "stats.trip.done",
  cancelled: "stats.trip.cancelled",
};

export class TripHistory {
  constructor() {
    this.doc = null; // the last `trips` reply, and the offset its times are shown with
    this.offset = 0;
    this.list = el("ul", { class: "stats-trips", "data-i18n-aria-label": "stats.trips.title" });
    this.note = el("p", { class: "muted stats-trip-note" });
    this.shown = TRIPS_PAGE;
    this.several = false; // the trips span several days: each says its day
    // A trip's row is built again only when it, the offset, the days or the language changed: a
    // trip unchanged keeps its row, opened or not.
    this.rows = new KeyedList(this.list, {
      key: (trip) => trip.id,
      signature: (trip) => [trip, this.offset, this.several, lang()],
      build: (trip) => this._trip(trip, this.offset, this.several, this._open.has(String(trip.id))),
    });
    this._open = new Set();
    this.more = el("button", {
      type: "button",
      class: "secondary",
      hidden: true,
      onclick: () => {
        this.shown += TRIPS_PAGE;
        this.render(this.doc, this.offset);
      },
    });
  }

  /** Another range: its latest trips first, none of them open. */
  reset() {
    this.shown = TRIPS_PAGE;
    this.rows.clear();
  }

  render(doc, offset) {
    this.doc = doc;
    this.offset = offset;
    this.several = new Set(doc.trips.map((tr) => csvTime(tr.started ?? tr.created, offset).slice(0, 10))).size > 1;
    this.note.textContent = doc.more ? t("stats.trips.more", { count: doc.trips.length }) : doc.trips.length ? "" : t("stats.trips.none");
    this.note.hidden = !this.note.textContent;
    // Newest first: the trip an owner asks about is usually a recent one. Opened ones stay open.
    this._open = new Set([...this.list.querySelectorAll("details[open]")].map((d) => d.dataset.trip));
    const trips = [...doc.trips].reverse();
    const shown = trips.slice(0, this.shown);
    this.rows.update(shown);
    const left = trips.length - shown.length;
    this.more.hidden = left <= 0;
    this.more.textContent = t("stats.trips.showMore", { count: Math.min(left, TRIPS_PAGE) });
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
          el("span", { class: "stop-outcome" }, outcome(s, offset)),
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
}

/** A stop's end in words: served, cancelled, skipped by someone, or timed out. */
function outcome(s, offset) {
  const time = clock(s.ended, offset);
  if (s.outcome === "done") return t("stats.stop.done", { time });
  if (s.outcome === "cancelled") return t("stats.stop.cancelled", { time });
  if (s.outcome === "skipped" && s.by) return t("stats.stop.skippedBy", { time, who: s.by.replace(/^user:/, "") });
  if (s.outcome === "skipped") return t("stats.stop.timedOut", { time });
  return t("stats.stop.pending");
}
