// The Restaurant tab's head office (issue 34): a restaurant of a chain sends everything it
// records to the chain's head office; this card says whether the head office is reached now and
// what still waits on this box — the outbox's size and its oldest update not sent yet (the
// protocol's `chain` verb). A card only for a restaurant in a chain; otherwise one discreet line.
//
// Read when the tab is opened, then every 20 s while the tab stays shown on a visible page;
// nothing is asked while another tab is open or the tablet sleeps (stream only what is shown).

import { el, formatTime } from "../../ui.js";
import { t } from "../../i18n.js";

const REFRESH_MS = 20000;

/** A count as the page's language writes it ("1,240"; i18n picks the plural from the text). */
function number(n) {
  return Number(n).toLocaleString(document.documentElement.lang || undefined);
}

export class ChainSection {
  /** `panel`: the Restaurant tab's panel (hidden while another tab is shown). */
  constructor(conn, live, panel) {
    this.conn = conn;
    this.live = live;
    this.panel = panel;
    this.chain = null; // the last reply
    this.timer = null;
    this.line = el("p", { class: "chain-line", "data-testid": "chain-line" });
    this.waiting = el("p", { class: "chain-waiting", "data-testid": "chain-waiting" });
    this.kept = el("p", { class: "muted chain-kept", "data-testid": "chain-kept" });
    this.where = el("p", { class: "muted chain-where" });
    this.card = el(
      "div",
      { class: "card" },
      el("h2", { id: "rest-chain-title", "data-i18n": "owner.chain.title" }),
      this.line,
      this.waiting,
      this.kept,
      this.where,
    );
    this.off = el("p", { class: "muted", "data-i18n": "owner.chain.off" });
    // Nothing shown until the server has said whether this restaurant is in a chain.
    this.section = el("section", { class: "rest-chain", hidden: true }, this.card, this.off);
    document.addEventListener("visibilitychange", () => this._follow());
  }

  /** The tab was opened: read now, and again every 20 s while it stays shown. */
  load() {
    this._stop();
    this._read();
  }

  _shown() {
    return !this.panel.hidden && document.visibilityState === "visible";
  }

  /** The page was hidden or shown again: stop asking, or read at once and go on. */
  _follow() {
    if (!this._shown()) this._stop();
    else if (!this.timer) this._read();
  }

  _stop() {
    clearTimeout(this.timer);
    this.timer = null;
  }

  async _read() {
    this._stop();
    this.timer = setTimeout(() => (this._shown() ? this._read() : this._stop()), REFRESH_MS);
    try {
      this.chain = (await this.conn.request({ clientmsg: "chain" })).chain;
    } catch {
      return; // offline, or not an owner's session: what was shown stays, the next read tells
    }
    this.render();
  }

  /** A time on the server's clock: "13:58", or with its day when that is not today. */
  _when(epoch) {
    const locale = document.documentElement.lang || undefined;
    const day = (s) => new Date(s * 1000).toLocaleDateString(locale, { day: "numeric", month: "short" });
    return day(epoch) === day(this.live.clock.now()) ? formatTime(epoch) : `${day(epoch)} ${formatTime(epoch)}`;
  }

  render() {
    const c = this.chain;
    if (!c) return;
    this.section.hidden = false;
    this.section.classList.toggle("off", !c.configured);
    // A region named "Head office" only in a chain: otherwise the line is all there is.
    if (c.configured) this.section.setAttribute("aria-labelledby", "rest-chain-title");
    else this.section.removeAttribute("aria-labelledby");
    this.card.hidden = !c.configured;
    this.off.hidden = c.configured;
    if (!c.configured) return;
    const box = c.outbox;
    this.card.classList.toggle("trouble", !c.connected);
    let line = t(c.connected ? "owner.chain.connected" : "owner.chain.notConnected");
    if (!c.connected) line += " " + (box.sent_at ? t("owner.chain.lastSent", { time: this._when(box.sent_at) }) : t("owner.chain.neverSent"));
    this.line.textContent = line;
    this.waiting.textContent =
      box.unsent > 0 && box.oldest_unsent_at
        ? t("owner.chain.waiting", { count: number(box.unsent), time: this._when(box.oldest_unsent_at) })
        : t("owner.chain.allSent");
    const kept = t("owner.chain.kept", { count: number(box.size) });
    this.kept.textContent = c.connected ? kept : `${t("owner.chain.resumes")} ${kept}`;
    this.where.textContent = t("owner.chain.where", { site: c.site, broker: c.broker });
  }
}
