// The overview: one card per site, drawn again only when what it shows changed.
//
// Every poll brings every site (GET /api/sites). Each card keeps the JSON of what it shows
// (not the whole reply: a site heard from again, with nothing new, is the same card), and a
// card whose JSON is unchanged keeps its very node; only a changed card is built again and put
// in its place. A language change draws them all again.

import { el } from "./dom.js";
import { count, wait } from "./format.js";
import { t } from "./i18n.js";
import { alertItem, robotItem, stateOf, stateWords, syncWords } from "./words.js";

/** The part of a site's record its card shows (and a day, for times shown with their day). */
function shown(site, now) {
  const down = stateOf(site) === "down";
  const today = site.today || {};
  return JSON.stringify({
    state: stateOf(site),
    heard: down ? (site.heard_at ?? site.state_at) : null,
    behind: site.behind,
    robots: site.robots,
    alerts: site.alerts,
    today: [today.delivered, today.wait_p50, today.wait_max],
    day: new Date(now * 1000).toDateString(),
  });
}

export function figure(label, value, cls) {
  return el("div", { class: `figure ${cls}` }, el("dt", {}, label), el("dd", {}, value));
}

export class Overview {
  constructor(list, { href }) {
    this.list = list;
    this.href = href; // site -> the address of its page
    this.cards = new Map(); // site -> {node, json}
    this.sites = [];
  }

  /** Forget every card's JSON: the next update draws them all (a language change). */
  invalidate() {
    for (const card of this.cards.values()) card.json = null;
  }

  /** Draw the centre's reply: only the cards whose shown part changed. */
  update(reply) {
    const now = reply.now;
    this.sites = reply.sites;
    const seen = new Set();
    let before = null; // keep the centre's order (by name) with the fewest moves
    for (const site of reply.sites) {
      seen.add(site.site);
      const json = shown(site, now);
      let card = this.cards.get(site.site);
      if (!card || card.json !== json) {
        const node = this.card(site, now);
        if (card) card.node.replaceWith(node);
        card = { node, json };
        this.cards.set(site.site, card);
      }
      const next = before ? before.nextSibling : this.list.firstChild;
      if (next !== card.node) this.list.insertBefore(card.node, next);
      before = card.node;
    }
    for (const [name, card] of this.cards) {
      if (!seen.has(name)) {
        card.node.remove();
        this.cards.delete(name);
      }
    }
  }

  card(site, now) {
    const state = stateOf(site);
    const [headline, detail] = stateWords(site, now);
    const nameId = `card-${site.site}`;
    const today = site.today || {};
    return el(
      "li",
      { class: `site-card card state-${state}`, "data-site": site.site, "data-state": state },
      el(
        "article",
        { "aria-labelledby": nameId },
        el("h2", { class: "site-name" }, el("a", { id: nameId, href: this.href(site.site) }, site.site)),
        el(
          "p",
          { class: `site-state ${state}` },
          el("strong", {}, headline),
          detail ? el("span", { class: "site-heard" }, detail) : null,
        ),
        el("p", { class: Number(site.behind) > 0 ? "site-sync behind" : "site-sync" }, syncWords(site)),
        el("h3", {}, t("today.title")),
        el(
          "dl",
          { class: "figures" },
          figure(t("fig.delivered"), count(today.delivered ?? 0), "delivered"),
          figure(t("fig.typicalWait"), wait(today.wait_p50), "typical"),
          figure(t("fig.longestWait"), wait(today.wait_max), "longest"),
        ),
        el("h3", {}, t("site.robots")),
        site.robots.length
          ? el("ul", { class: "robots" }, ...site.robots.map((r) => robotItem(r, now)))
          : el("p", { class: "muted" }, t("site.noRobots")),
        el("h3", {}, t("site.alerts")),
        site.alerts.length
          ? el("ul", { class: "alerts" }, ...site.alerts.map((a) => alertItem(a, now)))
          : el("p", { class: "muted" }, t("site.noAlerts")),
      ),
    );
  }

  /** "3 restaurants, 1 not connected". */
  summary() {
    const down = this.sites.filter((s) => stateOf(s) === "down").length;
    const all = t("overview.count", { count: this.sites.length, n: count(this.sites.length) });
    return down ? t("overview.countDown", { all, count: down, n: count(down) }) : all;
  }
}
