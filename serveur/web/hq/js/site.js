// One site's page: how it is now (from the overview's last word), its figures for each service
// day and its trip history (GET /api/sites/<site>/figures and /trips), and a way back.

import { el, say } from "./dom.js";
import { DASH, clock, count, dayWords, wait } from "./format.js";
import { t } from "./i18n.js";
import { LoggedOut, get } from "./api.js";
import { figure } from "./overview.js";
import { stateOf, stateWords, syncWords } from "./words.js";

const TRIP_STATUS = {
  queued: "trip.status.queued",
  active: "trip.status.active",
  done: "trip.status.done",
  cancelled: "trip.status.cancelled",
};
const TRIP_KIND = { bussing: "trip.kind.bussing", cruise: "trip.kind.cruise" };

export class SitePage {
  constructor(root, { onLoggedOut, back }) {
    this.onLoggedOut = onLoggedOut;
    this.site = null;
    this.record = null; // the overview's last record of this site
    this.figures = null;
    this.trips = null;
    this.failed = false;
    this.seq = 0;
    this.back = el("button", { type: "button", class: "secondary back", onclick: back });
    this.title = el("h2", { id: "site-title", class: "site-title", tabindex: "-1" });
    this.status = el("div", { class: "site-now" });
    this.state = el("p", { class: "muted", role: "status" });
    this.daysTitle = el("h3", { id: "site-days-title" });
    this.days = el("div", { class: "days-box" });
    this.tripsTitle = el("h3", { id: "site-trips-title" });
    this.tripsHint = el("p", { class: "muted" });
    this.tripsNote = el("p", { class: "muted" });
    this.tripList = el("ul", { class: "trips", "aria-labelledby": "site-trips-title" });
    root.append(
      this.back,
      this.title,
      this.status,
      this.state,
      el("section", { class: "card", "aria-labelledby": "site-days-title" }, this.daysTitle, this.days),
      el("section", { class: "card", "aria-labelledby": "site-trips-title" }, this.tripsTitle, this.tripsHint, this.tripsNote, this.tripList),
    );
  }

  /** Show `site` (its figures fetched anew), with the overview's `record` of it, if any. */
  async show(site, record) {
    const seq = ++this.seq;
    if (site !== this.site) {
      this.figures = this.trips = null;
      this.tripList.replaceChildren();
      this.days.replaceChildren();
    }
    this.site = site;
    this.record = record;
    this.failed = this.missing = false;
    this.render();
    try {
      const [figures, trips, sites] = await Promise.all([
        get(`/api/sites/${encodeURIComponent(site)}/figures`, { by: "day" }),
        get(`/api/sites/${encodeURIComponent(site)}/trips`),
        record ? null : get("/api/sites"), // opened from its address: how it is now
      ]);
      if (seq !== this.seq) return;
      if (sites) this.record = sites.sites.find((s) => s.site === site) || null;
      this.figures = figures;
      this.trips = trips;
    } catch (err) {
      if (seq !== this.seq) return;
      if (err instanceof LoggedOut) return this.onLoggedOut();
      this.failed = true;
      this.missing = err.status === 404;
    }
    this.render();
  }

  hidden() {
    this.seq++;
  }

  render() {
    this.back.textContent = t("sitepage.back");
    this.title.textContent = this.site || "";
    this.daysTitle.textContent = t("sitepage.days");
    this.tripsTitle.textContent = t("sitepage.trips");
    this.tripsHint.textContent = t("sitepage.tripsHint");
    const r = this.record;
    if (r) {
      const [headline, detail] = stateWords(r, Date.now() / 1000);
      this.status.replaceChildren(
        el("p", { class: `site-state ${stateOf(r)}` }, el("strong", {}, headline), detail ? el("span", { class: "site-heard" }, detail) : null),
        el("p", { class: Number(r.behind) > 0 ? "site-sync behind" : "site-sync" }, syncWords(r)),
      );
    } else this.status.replaceChildren();
    if (this.failed) say(this.state, this.missing ? t("sitepage.missing", { site: this.site }) : t("sitepage.failed"));
    else say(this.state, this.figures ? "" : t("sitepage.loading"));
    if (this.figures) this.days.replaceChildren(...this.daysList(this.figures));
    if (this.trips) this.tripsDrawn();
  }

  /** Each service day (the latest first) as a block of figures; the days' total after them. */
  daysList(doc) {
    const figures = (p) =>
      el(
        "dl",
        { class: "figures" },
        figure(t("fig.delivered"), count(p.delivered), "delivered"),
        figure(t("fig.typicalWait"), wait(p.wait_p50), "typical"),
        figure(t("fig.longestWait"), wait(p.wait_max), "longest"),
        figure(t("fig.within95"), wait(p.wait_p95), "within95"),
        figure(t("fig.trips"), count(p.trips), "trips"),
        figure(t("fig.returned"), count(p.returned), "returned"),
      );
    const periods = [...doc.periods].reverse();
    if (!periods.length) return [el("p", { class: "muted" }, t("sitepage.noDays"))];
    const days = el(
      "ol",
      { class: "days" },
      ...periods.map((p) => el("li", { class: "day", "data-day": p.period }, el("h4", {}, dayWords(p.period)), figures(p))),
    );
    if (periods.length < 2) return [days];
    return [days, el("div", { class: "day total" }, el("h4", {}, t("fig.total")), figures(doc.total))];
  }

  tripsDrawn() {
    const doc = this.trips;
    const open = new Set([...this.tripList.querySelectorAll("details[open]")].map((d) => d.dataset.trip));
    say(this.tripsNote, doc.more ? t("sitepage.tripsMore", { count: doc.trips.length, n: count(doc.trips.length) }) : doc.trips.length ? "" : t("sitepage.noTrips"));
    this.tripList.replaceChildren(...[...doc.trips].reverse().map((trip) => this.trip(trip, open.has(String(trip.id)))));
  }

  trip(trip, open) {
    const when = trip.started ?? trip.created;
    const status = TRIP_STATUS[trip.status] ? t(TRIP_STATUS[trip.status]) : String(trip.status);
    const parts = [
      el("span", { class: "trip-time" }, clock(when)),
      el("span", { class: "trip-id" }, TRIP_KIND[trip.kind] ? t(TRIP_KIND[trip.kind], { id: trip.id }) : t("trip.name", { id: trip.id })),
      el("span", { class: "trip-robot" }, trip.robot || t("trip.noRobot")),
      el("span", {}, t("trip.tables", { count: trip.stops.length, n: count(trip.stops.length) }) + ", " + t("trip.delivered", { count: trip.delivered, n: count(trip.delivered) })),
      trip.returned ? el("span", { class: "trip-returned" }, t("trip.returned", { count: trip.returned, n: count(trip.returned) })) : null,
      el("span", { class: `trip-status ${trip.status}` }, status),
    ].filter(Boolean);
    const stops = el(
      "ol",
      { class: "stops" },
      ...trip.stops.map((s) =>
        el(
          "li",
          {},
          el("strong", {}, t("stop.table", { table: s.table })),
          " ",
          el("span", {}, outcome(s)),
          s.dishes.length ? el("span", { class: "stop-dishes" }, s.dishes.map((d) => d.dish || "?").join(", ")) : null,
        ),
      ),
    );
    return el(
      "li",
      { class: "trip" },
      el(
        "details",
        { "data-trip": trip.id, open },
        el("summary", {}, ...parts.flatMap((p, i) => (i ? [" · ", p] : [p]))),
        el("p", { class: "muted" }, t("trip.times", { sent: clock(trip.created), left: clock(trip.left), ended: clock(trip.ended) })),
        stops,
      ),
    );
  }
}

/** A stop's end in words: served, cancelled, skipped by someone, or nobody collected. */
function outcome(s) {
  const time = s.ended ? clock(s.ended) : DASH;
  if (s.outcome === "done") return t("stop.done", { time });
  if (s.outcome === "cancelled") return t("stop.cancelled", { time });
  if (s.outcome === "skipped" && s.by) return t("stop.skippedBy", { time, who: String(s.by).replace(/^user:/, "") });
  if (s.outcome === "skipped") return t("stop.timedOut", { time });
  return t("stop.pending");
}
