// The Kitchen tab's tickets from the till: the dishes a ticket ordered, grouped on one card per
// ticket (its table, its number when the pattern reads one, when it arrived), each dish with the
// kitchen's own row (the panel gives it: Start cooking, Ready, Change, Void as for any dish);
// and, first, each ticket nobody understood, shown as it printed, with "Add a dish by hand"
// (the New order tab, at its table when the ticket names one) and "Done by hand" (`till
// by_hand`: its dishes are in, the ticket is handled).
//
// Cards are keyed by ticket and drawn only when their head changed; each card's dishes are a
// list of their own, so a dish marked cooking redraws its row alone.

import { act, byName, el, formatTime, KeyedList, toast } from "../../ui.js";
import { t } from "../../i18n.js";
import { printed, ticketNumber, ticketProblem } from "./tickets.js";

export class TicketCards {
  /** `dishRows`: the kitchen's KeyedList options for a dish's row; `addByHand(table|null)`:
   *  open New order. */
  constructor(conn, book, { dishRows, addByHand }) {
    this.conn = conn;
    this.book = book;
    this.dishRows = dishRows;
    this.addByHand = addByHand;
    this.unreadList = el("ul", { class: "ticket-list", "data-i18n-aria-label": "till.kitchen.unreadList" });
    this.ticketList = el("ul", { class: "ticket-list", "data-i18n-aria-label": "till.kitchen.tickets" });
    this.unreadRows = new KeyedList(this.unreadList, {
      key: (x) => x.id,
      signature: (x) => [x.lines, x.status, ticketProblem(x), x.reading && x.reading.table],
      build: (x) => this._unread(x),
    });
    this.ticketRows = new KeyedList(this.ticketList, {
      key: (g) => g.id,
      signature: (g) => [g.table, g.number, g.at],
      build: (g) => this._card(g),
    });
    this.section = el(
      "section",
      { class: "card till-card", "aria-labelledby": "kitchen-till-title", hidden: true },
      el("h2", { id: "kitchen-till-title", "data-i18n": "till.kitchen.title" }),
      this.unreadList,
      this.ticketList,
    );
  }

  /** Redraw what changed: `orders` are the dishes from the till still in the kitchen. */
  render(orders, byAge) {
    const groups = new Map(); // ticket id -> its card's model
    for (const o of orders) {
      if (!groups.has(o.ticket)) {
        const ticket = this.book.get(o.ticket);
        groups.set(o.ticket, {
          id: o.ticket,
          table: (ticket && ticket.table) || o.table,
          number: ticketNumber(ticket),
          at: ticket ? ticket.received_at : o.ordered_at,
          orders: [],
        });
      }
      groups.get(o.ticket).orders.push(o);
    }
    const cards = [...groups.values()].sort((a, b) => (a.at ?? 0) - (b.at ?? 0) || byName(a.table, b.table) || a.id - b.id);
    const unread = this.book.unread();
    this.unreadRows.update(unread);
    this.ticketRows.update(cards);
    for (const card of cards) this.ticketRows.node(card.id).dishes.update(card.orders.sort(byAge));
    this.section.hidden = !unread.length && !cards.length;
  }

  /** Same tickets, new words. */
  invalidate() {
    this.unreadRows.invalidate();
    this.ticketRows.invalidate();
  }

  _when(at) {
    return at ? el("p", { class: "ticket-when muted" }, t("till.kitchen.arrived", { time: formatTime(at) })) : null;
  }

  _card(g) {
    const title = g.number ? t("till.kitchen.cardNumbered", { table: g.table, ticket: g.number }) : t("till.kitchen.card", { table: g.table });
    const titleId = `ticket-${g.id}-title`;
    const list = el("ul", { class: "dish-list kitchen-list", "aria-labelledby": titleId });
    const node = el(
      "li",
      { class: "ticket-card", "data-ticket": g.id },
      el("h3", { id: titleId }, title),
      this._when(g.at),
      list,
    );
    node.dishes = new KeyedList(list, this.dishRows);
    return node;
  }

  _unread(x) {
    const table = (x.reading && x.reading.table) || null;
    const titleId = `ticket-${x.id}-title`;
    const problem = ticketProblem(x);
    return el(
      "li",
      { class: "ticket-card unread", "data-ticket": x.id, "aria-labelledby": titleId },
      el("h3", { id: titleId, class: "ticket-why" }, t("till.kitchen.unread")),
      this._when(x.received_at),
      problem ? el("p", { class: "ticket-problem" }, problem) : null,
      printed(x.lines),
      el(
        "div",
        { class: "row-actions" },
        el("button", {
          class: "secondary",
          type: "button",
          "data-focus-key": "add",
          "aria-label": t("till.kitchen.addByHandFor", { time: formatTime(x.received_at) }),
          text: t("till.kitchen.addByHand"),
          onclick: () => this.addByHand(table),
        }),
        el("button", {
          type: "button",
          "data-needs-online": true,
          "data-focus-key": "done",
          "aria-label": t("till.kitchen.doneByHandFor", { time: formatTime(x.received_at) }),
          text: t("till.kitchen.doneByHand"),
          onclick: (e) => this._done(x, e.currentTarget),
        }),
      ),
    );
  }

  async _done(ticket, button) {
    const reply = await act(button, () => this.conn.request({ clientmsg: "till", action: "by_hand", ticket: ticket.id }));
    if (reply) toast(t("till.kitchen.handled"));
  }
}
