// The till's tickets (issue 33): each kitchen ticket the restaurant's till printed, kept as it
// printed (its `lines`), what the owner's ticket pattern read on it (`reading`) and what became
// of it (`status`: ordered, unread, reprint, void, by_hand). The Kitchen tab follows the
// `tickets` topic only while it is shown (TicketBook.follow); the owner's Till section reads
// them with `till tickets`. What both say of a ticket is written here once: its printed lines,
// its number, what a reading found, and why a ticket was not understood.

import { el } from "../../ui.js";
import { t } from "../../i18n.js";
import { dishLabel } from "../dishes.js";

const TOPIC = "tickets";

/** The `tickets` topic, kept while a view shows it: id -> ticket. Emits "change". */
export class TicketBook extends EventTarget {
  constructor(conn) {
    super();
    this.conn = conn;
    this.tickets = new Map();
    conn.addEventListener("snapshot", (e) => {
      const snap = e.detail.data && e.detail.data[TOPIC];
      if (!Array.isArray(snap)) return;
      this.tickets.clear(); // newer than any update before it
      for (const ticket of snap) this.tickets.set(ticket.id, ticket);
      this._changed();
    });
    conn.addEventListener("update", (e) => {
      // A frame already on its way when the view stopped following: not shown any more.
      if (e.detail.topic !== TOPIC || !conn.topics.has(TOPIC)) return;
      this.tickets.set(e.detail.data.id, e.detail.data);
      this._changed();
    });
  }

  /** Follow the topic (`on`) or stop, forgetting what it held: only what is shown streams. */
  follow(on) {
    if (on) {
      this.conn.subscribe([TOPIC]);
      return;
    }
    this.conn.unsubscribe([TOPIC]);
    if (this.tickets.size) {
      this.tickets.clear();
      this._changed();
    }
  }

  get(id) {
    return this.tickets.get(id) ?? null;
  }

  /** The tickets nobody understood yet, oldest first. */
  unread() {
    return [...this.tickets.values()].filter((x) => x.status === "unread").sort(byArrival);
  }

  _changed() {
    this.dispatchEvent(new Event("change"));
  }
}

export function byArrival(a, b) {
  return a.received_at - b.received_at || a.id - b.id;
}

/** The ticket's lines as they printed, in a monospace block. */
export function printed(lines) {
  return el("pre", { class: "ticket-printed" }, lines.join("\n"));
}

/** The ticket's own number, as the till printed it, or null (the pattern reads none). */
export function ticketNumber(ticket) {
  return (ticket && ticket.reading && ticket.reading.ticket) || null;
}

/** What a reading found wrong, in words: no table, no dish; null when it was understood. */
export function readingProblem(reading) {
  if (!reading) return t("till.problem.noPattern");
  if (reading.problem === null || reading.problem === undefined) return null;
  if (!reading.table) return t("till.problem.noTable");
  if (!reading.dishes || !reading.dishes.length) return t("till.problem.noDish");
  return t("till.problem.other", { why: reading.problem });
}

/** Why a ticket was not understood, in words: no pattern yet (it has no reading), what its
 *  reading lacks, or the table it read is none of the map's. */
export function ticketProblem(ticket) {
  if (!ticket.reading) return t("till.problem.noPattern");
  const problem = readingProblem(ticket.reading);
  if (problem || !ticket.problem) return problem;
  return t("till.problem.notTable", { table: ticket.reading.table });
}

/** "Laksa ×2 (no chilli)": one dish as a ticket was read, written as any dish. */
export function readDish(dish) {
  return dishLabel({ dish: dish.name, quantity: dish.quantity, note: (dish.notes || []).join(", ") });
}

/** What a reading says in one line: "T12, ticket 1042: Laksa ×2 (no chilli), Teh" (or void),
 *  or its problem. */
export function readingWords(reading) {
  const problem = readingProblem(reading);
  if (problem) return problem;
  const dishes = reading.dishes.map(readDish).join(", ");
  const head = reading.ticket ? t("till.read.numbered", { table: reading.table, ticket: reading.ticket }) : reading.table;
  return t(reading.void ? "till.read.void" : "till.read.dishes", { head, dishes });
}
