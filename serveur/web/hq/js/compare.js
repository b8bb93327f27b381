// Comparison: every site's dishes delivered and typical wait, per service day (the latest
// DAYS days any site worked), from GET /api/figures?by=day. Fetched only while shown: when the
// tab is opened, then every minute while it stays open; nothing while it is hidden.

import { el, say } from "./dom.js";
import { DASH, count, dayWords, wait } from "./format.js";
import { t } from "./i18n.js";
import { LoggedOut, get } from "./api.js";

const DAYS = 7;
const REFRESH_MS = 60_000;

export class Compare {
  constructor(root, { onLoggedOut }) {
    this.onLoggedOut = onLoggedOut;
    this.doc = null;
    this.timer = 0;
    this.open = false;
    this.seq = 0;
    this.state = el("p", { class: "muted", role: "status" });
    this.note = el("p", { class: "muted note" });
    this.swipe = el("p", { class: "muted note", hidden: true }); // said when the table is wider than the screen
    this.box = el("div", { class: "table-scroll", tabindex: "0", role: "region", "aria-labelledby": "compare-title" });
    root.append(
      el("h2", { id: "compare-title", tabindex: "-1" }),
      el("p", { class: "muted explain", id: "compare-explain" }),
      this.state,
      this.swipe,
      this.box,
      this.note,
    );
    new ResizeObserver(() => this.fits()).observe(this.box);
    this.title = root.querySelector("#compare-title");
    this.explain = root.querySelector("#compare-explain");
    this.render();
  }

  /** The tab was opened: fetch now, then every minute while it stays open. */
  shown() {
    if (this.open) return;
    this.open = true;
    this.load();
  }

  hidden() {
    this.open = false;
    clearTimeout(this.timer);
    this.seq++; // a reply still on its way is not drawn
  }

  async load() {
    clearTimeout(this.timer);
    const seq = ++this.seq;
    if (!this.doc) say(this.state, t("compare.loading"));
    try {
      const doc = await get("/api/figures", { by: "day" });
      if (seq !== this.seq) return;
      this.doc = doc;
      this.failed = false;
    } catch (err) {
      if (seq !== this.seq) return;
      if (err instanceof LoggedOut) return this.onLoggedOut();
      this.failed = true;
    }
    this.render();
    if (this.open) this.timer = setTimeout(() => this.load(), REFRESH_MS);
  }

  render() {
    this.title.textContent = t("compare.title");
    this.explain.textContent = t("compare.explain");
    if (!this.doc) {
      say(this.state, this.failed ? t("compare.failed") : this.open ? t("compare.loading") : "");
      this.box.hidden = true;
      return;
    }
    const sites = Object.keys(this.doc.sites).sort();
    const byDay = new Map(); // day -> site -> period
    for (const site of sites) {
      for (const p of this.doc.sites[site].periods) {
        if (!byDay.has(p.period)) byDay.set(p.period, new Map());
        byDay.get(p.period).set(site, p);
      }
    }
    const days = [...byDay.keys()].sort().reverse().slice(0, DAYS);
    say(this.state, this.failed ? t("compare.failed") : days.length ? "" : t("compare.empty"));
    say(this.note, byDay.size > DAYS ? t("compare.more", { count: DAYS }) : "");
    this.box.hidden = !days.length;
    if (!days.length) return;
    const head = el(
      "thead",
      {},
      el(
        "tr",
        {},
        el("th", { scope: "col", rowspan: "2" }, t("compare.site")),
        ...days.map((d) => el("th", { scope: "colgroup", colspan: "2", "data-day": d }, dayWords(d))),
      ),
      el("tr", {}, ...days.flatMap(() => [el("th", { scope: "col" }, t("fig.delivered")), el("th", { scope: "col" }, t("fig.typicalWait"))])),
    );
    const rows = sites.map((site) =>
      el(
        "tr",
        { "data-site": site },
        el("th", { scope: "row" }, site),
        ...days.flatMap((d) => {
          const p = byDay.get(d).get(site);
          return [
            el("td", { class: "num delivered", "data-day": d }, p ? count(p.delivered) : DASH),
            el("td", { class: "num typical", "data-day": d }, p ? wait(p.wait_p50) : DASH),
          ];
        }),
      ),
    );
    this.box.replaceChildren(
      el("table", { class: "compare" }, el("caption", { class: "visually-hidden" }, t("compare.title")), head, el("tbody", {}, ...rows)),
    );
    this.fits();
  }

  /** On a narrow screen the table scrolls in its box: say so. */
  fits() {
    const wider = !this.box.hidden && this.box.scrollWidth > this.box.clientWidth + 1;
    say(this.swipe, wider ? t("compare.swipe") : "");
  }
}
