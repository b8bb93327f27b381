// The Till section's "how to read the tickets": serveur does not guess how a till lays its
// tickets out, the owner shows it. The owner picks one ticket the till printed (`till
// tickets`), taps a line and says what it is — the table (and which table), a dish, a note
// under a dish, the ticket's number, the words of a void ticket, a line to ignore; "Propose"
// (`till propose` with the marks) shows how this ticket reads and how every kept ticket would
// read; "Save" (`till setup` with the pattern) keeps it, and the tickets nobody understood are
// read again: the section says how many became orders.

import { act, byName, describeError, el, formatTime, KeyedList } from "../../ui.js";
import { t } from "../../i18n.js";
import { readingProblem, readingWords } from "./tickets.js";

// What a line may be (the wire's `as`), in the owner's words.
const MARKS = {
  table: "owner.till.mark.table",
  dish: "owner.till.mark.dish",
  note: "owner.till.mark.note",
  ticket: "owner.till.mark.ticket",
  void: "owner.till.mark.void",
  ignore: "owner.till.mark.ignore",
};
// The marks a ticket has one line of (any number of lines may be ignored).
const ONCE = ["table", "dish", "note", "ticket", "void"];

const STATUS = {
  unread: "owner.till.status.unread",
  ordered: "owner.till.status.ordered",
  reprint: "owner.till.status.reprint",
  void: "owner.till.status.void",
  by_hand: "owner.till.status.byHand",
};

const LIMIT = 50;

/** The table a line most likely names: a table's name as a word of it, else the table whose
 *  number comes first in the line ("Table: 12  Guests: 3" for T12); null when none. */
function guessTable(line, tables) {
  const words = (line.match(/\w+/g) || []).map((w) => w.toLowerCase());
  const named = tables.find((name) => words.includes(name.toLowerCase()));
  if (named) return named;
  for (const number of line.match(/\d+/g) || []) {
    const numbered = tables.find((name) => (name.match(/\d+$/) || [""])[0] === number);
    if (numbered) return numbered;
  }
  return null;
}

/** A kept ticket in a few words: what it read, else its first printed lines. */
function summary(ticket) {
  if (ticket.reading && !readingProblem(ticket.reading)) return readingWords(ticket.reading);
  return ticket.lines.filter((l) => l.trim()).slice(0, 3).map((l) => l.trim()).join(" / ");
}

export class PatternSetup {
  /** `onSaved(tillState)`: the pattern was saved, the server's state given. */
  constructor(conn, live, onSaved) {
    this.conn = conn;
    this.live = live;
    this.onSaved = onSaved;
    this.tickets = []; // the kept tickets, newest first
    this.chosen = null; // the ticket being marked
    this.marks = new Map(); // line index -> {as, table}
    this.open = null; // the line whose "what is it" is open
    this.proposal = null; // the pattern the last Propose made, for Save
    this.preview = []; // how each kept ticket reads with it

    this.reloadBtn = el("button", { type: "button", class: "secondary", "data-needs-online": true, "data-i18n": "owner.till.reload", onclick: (e) => this.load(e.currentTarget) });
    this.ticketList = el("ul", { class: "rest-list till-tickets", "data-i18n-aria-label": "owner.till.ticketsTitle" });
    this.ticketRows = new KeyedList(this.ticketList, {
      key: (x) => x.id,
      signature: (x) => [x.status, x.received_at, summary(x), x.id === (this.chosen && this.chosen.id)],
      build: (x) => this._ticketRow(x),
      empty: () => el("li", { class: "muted", text: t("owner.till.noTickets") }),
    });
    this.linesTitle = el("h4", { id: "till-lines-title" });
    this.lineList = el("ol", { class: "till-lines", "aria-labelledby": "till-lines-title" });
    this.lineRows = new KeyedList(this.lineList, {
      key: (l) => l.index,
      signature: (l) => [l.text, this.marks.get(l.index) ?? null, this.open === l.index, this._tables()],
      build: (l) => this._lineRow(l),
    });
    this.proposeBtn = el("button", { type: "button", class: "primary", "data-needs-online": true, "data-i18n": "owner.till.propose", onclick: (e) => this._propose(e.currentTarget) });
    this.saveBtn = el("button", { type: "button", class: "primary", "data-needs-online": true, "data-i18n": "owner.till.savePattern", disabled: true, onclick: (e) => this._save(e.currentTarget) });
    this.why = el("p", { class: "rest-error", role: "alert" });
    this.whyMore = el("details", { class: "till-why", hidden: true }, el("summary", { "data-i18n": "owner.till.whyMore" }), el("p"));
    this.reads = el("p", { class: "till-reads", "data-testid": "till-reads" });
    this.previewTitle = el("h4", { id: "till-preview-title", hidden: true });
    this.previewList = el("ul", { class: "rest-list till-preview", "aria-labelledby": "till-preview-title" });
    this.previewRows = new KeyedList(this.previewList, {
      key: (p) => p.ticket,
      signature: (p) => [readingWords(p.reading), p.ticket === (this.chosen && this.chosen.id)],
      build: (p) => this._previewRow(p),
    });
    this.status = el("p", { class: "rest-map-progress", role: "status", "aria-live": "polite" });
    this.work = el(
      "div",
      { class: "till-work", hidden: true },
      this.linesTitle,
      el("p", { class: "muted rest-hint", "data-i18n": "owner.till.linesNote" }),
      this.lineList,
      el("div", { class: "form-buttons" }, this.proposeBtn, this.saveBtn),
      this.why,
      this.whyMore,
      this.reads,
      this.previewTitle,
      this.previewList,
    );
    this.section = el(
      "div",
      { class: "till-pattern", role: "group", "aria-labelledby": "rest-till-pattern-title" },
      el("h3", { id: "rest-till-pattern-title", "data-i18n": "owner.till.patternTitle" }),
      el("p", { class: "muted", "data-i18n": "owner.till.patternNote" }),
      el("h4", { "data-i18n": "owner.till.ticketsTitle" }),
      this.ticketList,
      el("div", { class: "form-buttons" }, this.reloadBtn),
      this.work,
      this.status,
    );
    live.addEventListener("change", (e) => e.detail.topic === "waypoints" && this.chosen && this._drawLines());
  }

  /** Read the kept tickets afresh (the tab opened, the owner asked, a pattern was saved). */
  async load(button = null) {
    const read = () => this.conn.request({ clientmsg: "till", action: "tickets", limit: LIMIT }, { resend: true });
    let reply;
    if (button) reply = await act(button, read);
    else {
      try {
        reply = await read();
      } catch {
        return; // not the owner (the tab is not shown then), or offline: the list stays
      }
    }
    if (!reply) return;
    this.tickets = reply.tickets || [];
    if (this.chosen) this.chosen = this.tickets.find((x) => x.id === this.chosen.id) ?? this.chosen;
    this.ticketRows.update(this.tickets);
  }

  /** New words: every row again. */
  relabel() {
    for (const rows of [this.ticketRows, this.lineRows, this.previewRows]) rows.invalidate();
    this.ticketRows.update(this.tickets);
    if (this.chosen) this._drawLines();
    this._drawPreview();
  }

  _tables() {
    return [...this.live.waypoints.values()].filter((w) => w.kind === "table").map((w) => w.name).sort(byName);
  }

  _ticketRow(x) {
    const time = formatTime(x.received_at);
    const chosen = this.chosen && this.chosen.id === x.id;
    return el(
      "li",
      { class: "rest-place", "data-ticket": x.id },
      el("span", { class: "rest-name", text: time }),
      el("span", { class: x.status === "unread" ? "problem" : "rest-kind", text: t(STATUS[x.status] || "owner.till.status.other") }),
      el("span", { class: "rest-pos till-summary", text: summary(x) }),
      el(
        "div",
        { class: "row-actions" },
        el("button", {
          type: "button",
          class: "secondary",
          "aria-pressed": String(Boolean(chosen)),
          "aria-label": t("owner.till.chooseFor", { time }),
          text: t("owner.till.choose"),
          onclick: () => this._choose(x),
        }),
      ),
    );
  }

  _choose(ticket) {
    this.chosen = ticket;
    this.marks.clear();
    this.open = null;
    this._forget();
    this.lineRows.clear();
    this.linesTitle.textContent = t("owner.till.linesTitle", { time: formatTime(ticket.received_at) });
    this.work.hidden = false;
    this.ticketRows.update(this.tickets);
    this._drawLines();
    const first = this.lineList.querySelector("button");
    if (first) first.focus();
  }

  /** The proposal and its preview no longer hold (the marks changed, another ticket). */
  _forget() {
    this.proposal = null;
    this.saveBtn.disabled = true;
    this.why.textContent = "";
    this.whyMore.hidden = true;
    this.reads.textContent = "";
    this.preview = [];
    this._drawPreview();
  }

  _drawLines() {
    this.lineRows.update(this.chosen.lines.map((text, index) => ({ text, index })));
  }

  _markWords(mark) {
    return mark.as === "table" ? t("owner.till.markedTable", { table: mark.table }) : t(MARKS[mark.as]);
  }

  _lineRow({ text, index }) {
    if (!text.trim()) return el("li", { class: "till-line blank", "data-line": index });
    const mark = this.marks.get(index);
    const open = this.open === index;
    const chooserId = `till-line-${index}-kind`;
    const words = text.trim().replace(/\s+/g, " ");
    return el(
      "li",
      { class: mark ? "till-line marked" : "till-line", "data-line": index },
      el("button", {
        type: "button",
        class: "line-text",
        "data-focus-key": "line",
        "aria-expanded": String(open),
        "aria-controls": open ? chooserId : null,
        "aria-label": mark ? t("owner.till.lineMarked", { n: index + 1, text: words, mark: this._markWords(mark) }) : t("owner.till.line", { n: index + 1, text: words }),
        text,
        onclick: () => {
          this.open = open ? null : index;
          this._drawLines();
        },
      }),
      mark ? el("span", { class: "line-mark", "aria-hidden": "true" }, this._markWords(mark)) : null,
      open ? this._chooser(index, mark, chooserId, text) : null,
    );
  }

  /** "What is line 3?": one choice (none, or a kind), and for the table which table it is. */
  _chooser(index, mark, id, text) {
    const name = `till-line-${index}`;
    const choice = (value, key) =>
      el(
        "label",
        { class: "check" },
        el("input", {
          type: "radio",
          name,
          value,
          checked: (mark ? mark.as : "") === value,
          "data-focus-key": `as-${value || "none"}`,
          onchange: () => this._mark(index, value, text),
        }),
        el("span", { text: t(key) }),
      );
    const tables = this._tables();
    const pick =
      mark && mark.as === "table"
        ? el(
            "div",
            { class: "rest-field" },
            el("label", { for: `${name}-table`, text: t("owner.till.whichTable") }),
            el(
              "select",
              {
                id: `${name}-table`,
                "data-focus-key": "table",
                onchange: (e) => {
                  this.marks.set(index, { as: "table", table: e.currentTarget.value });
                  this._forget();
                  this._drawLines();
                },
              },
              tables.map((n) => el("option", { value: n, text: n, selected: n === mark.table })),
            ),
          )
        : null;
    return el(
      "fieldset",
      { id, class: "till-kind" },
      el("legend", { text: t("owner.till.whatIs", { n: index + 1 }) }),
      choice("", "owner.till.mark.none"),
      Object.entries(MARKS).map(([value, key]) => choice(value, key)),
      pick,
      el("div", { class: "form-buttons" }, el("button", {
        type: "button",
        class: "secondary",
        "data-focus-key": "done",
        text: t("owner.till.lineDone"),
        onclick: () => {
          this.open = null;
          this._drawLines();
          const line = this.lineList.querySelector(`[data-line="${index}"] .line-text`);
          if (line) line.focus();
        },
      })),
    );
  }

  _mark(index, as, text) {
    if (!as) this.marks.delete(index);
    else {
      // One line holds the table, one is the dish shown, ...: marking another moves the mark.
      if (ONCE.includes(as)) for (const [i, m] of this.marks) if (m.as === as && i !== index) this.marks.delete(i);
      const mark = { as };
      if (as === "table") mark.table = guessTable(text, this._tables()) ?? this._tables()[0] ?? "";
      this.marks.set(index, mark);
    }
    this._forget();
    this._drawLines();
  }

  _wire() {
    return [...this.marks]
      .sort((a, b) => a[0] - b[0])
      .map(([line, m]) => (m.as === "table" ? { line, as: "table", table: m.table } : { line, as: m.as }));
  }

  _refused(err) {
    this.why.textContent = describeError(err);
    // Why the marks make no pattern is the server's own sentence: folded under the words.
    const more = err && err.code === "invalid_field" && err.message;
    this.whyMore.hidden = !more;
    this.whyMore.querySelector("p").textContent = more || "";
  }

  async _propose(button) {
    this._forget();
    const marks = this._wire();
    if (!marks.some((m) => m.as === "table" && m.table) || !marks.some((m) => m.as === "dish")) {
      this.why.textContent = t("owner.till.needMarks");
      return;
    }
    button.disabled = true;
    let reply;
    try {
      reply = await this.conn.request({ clientmsg: "till", action: "propose", ticket: this.chosen.id, marks });
    } catch (err) {
      this._refused(err);
      return;
    } finally {
      button.disabled = false;
    }
    this.proposal = reply.pattern;
    this.preview = reply.preview || [];
    const own = this.preview.find((p) => p.ticket === this.chosen.id);
    this.reads.textContent = own ? t("owner.till.reads", { reading: readingWords(own.reading) }) : "";
    this.saveBtn.disabled = false;
    this._drawPreview();
  }

  _drawPreview() {
    const preview = this.preview || [];
    const understood = preview.filter((p) => !readingProblem(p.reading)).length;
    this.previewTitle.hidden = !preview.length;
    this.previewTitle.textContent = preview.length ? t("owner.till.previewTitle", { count: preview.length, understood }) : "";
    this.previewRows.update(preview);
  }

  _previewRow(p) {
    const ticket = this.tickets.find((x) => x.id === p.ticket);
    const problem = readingProblem(p.reading);
    const own = this.chosen && p.ticket === this.chosen.id;
    return el(
      "li",
      { class: problem ? "rest-place till-preview-problem" : "rest-place", "data-ticket": p.ticket },
      el("span", { class: "rest-name", text: ticket ? formatTime(ticket.received_at) : t("owner.till.ticketNo", { id: p.ticket }) }),
      own ? el("span", { class: "rest-kind", text: t("owner.till.thisTicket") }) : null,
      el("span", { class: problem ? "problem till-summary" : "till-summary", text: readingWords(p.reading) }),
    );
  }

  async _save(button) {
    const reply = await act(button, () => this.conn.request({ clientmsg: "till", action: "setup", pattern: this.proposal }));
    if (!reply) return;
    const count = (reply.read || []).length;
    this.status.textContent = t("owner.till.patternSaved", { count });
    this.saveBtn.disabled = true;
    this.onSaved(reply.till);
    await this.load();
  }
}
