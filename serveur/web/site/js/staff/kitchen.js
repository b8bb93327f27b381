// Kitchen: the dishes ordered and not ready yet, oldest first. "Start cooking" and "Ready" are
// the kitchen's steps (a ready dish waits at the pass, in Issue task); a dish can be edited
// (quantity, note) or voided until it leaves the pass.
//
// Dishes that came from the restaurant's till (`order.ticket`) are shown on one card per ticket
// instead (till/cards.js), with the same rows; a ticket nobody understood is shown as it
// printed. The `tickets` topic streams only while this tab is shown (`shown(on)`).

import { byName, el, formatDuration, KeyedList } from "../ui.js";
import { onLangChange, t } from "../i18n.js";
import { dishLabel, dishStep, editButtons } from "./dishes.js";
import { TicketBook } from "./till/tickets.js";
import { TicketCards } from "./till/cards.js";

const byAge = (a, b) => (a.ordered_at ?? 0) - (b.ordered_at ?? 0) || byName(a.table, b.table) || a.id - b.id;
const inKitchen = (o) => o.status === "ordered" || o.status === "cooking";

export class KitchenPanel {
  /** `addByHand(table|null)`: open New order for a ticket's dishes (at its table if known). */
  constructor(root, conn, live, { addByHand }) {
    this.conn = conn;
    this.live = live;
    this.book = new TicketBook(conn);
    // A dish's row, the same in the lists and on a ticket's card.
    const dishRows = {
      key: (o) => o.id,
      signature: (o) => [dishLabel(o), o.table, o.status],
      build: (o) => this._row(o),
    };
    this.tickets = new TicketCards(conn, this.book, { dishRows, addByHand });
    this.ordered = el("ul", { class: "dish-list kitchen-list", "data-i18n-aria-label": "kitchen.ordered" });
    this.cooking = el("ul", { class: "dish-list kitchen-list", "data-i18n-aria-label": "kitchen.cooking" });
    root.append(
      el(
        "div",
        { class: "kitchen-grid" },
        this.tickets.section,
        el(
          "section",
          { class: "card", "aria-labelledby": "kitchen-ordered-title" },
          el("h2", { id: "kitchen-ordered-title", "data-i18n": "kitchen.ordered" }),
          this.ordered,
        ),
        el(
          "section",
          { class: "card", "aria-labelledby": "kitchen-cooking-title" },
          el("h2", { id: "kitchen-cooking-title", "data-i18n": "kitchen.cooking" }),
          this.cooking,
        ),
      ),
    );
    const rows = (emptyKey) => ({ ...dishRows, empty: () => el("li", { class: "muted" }, t(emptyKey)) });
    this.orderedRows = new KeyedList(this.ordered, rows("kitchen.orderedEmpty"));
    this.cookingRows = new KeyedList(this.cooking, rows("kitchen.cookingEmpty"));
    live.addEventListener("change", (e) => e.detail.topic === "orders" && this.render());
    this.book.addEventListener("change", () => this.render());
    setInterval(() => this._tick(), 1000);
    onLangChange(() => {
      this.orderedRows.invalidate();
      this.cookingRows.invalidate();
      this.tickets.invalidate();
      this.render();
    });
    this.render();
  }

  /** The tab is shown (`on`) or left: the till's tickets stream only while it is shown. */
  shown(on) {
    this.book.follow(on);
  }

  render() {
    const all = [...this.live.orders.values()];
    const own = all.filter((o) => o.ticket === null || o.ticket === undefined);
    this.orderedRows.update(own.filter((o) => o.status === "ordered").sort(byAge));
    this.cookingRows.update(own.filter((o) => o.status === "cooking").sort(byAge));
    this.tickets.render(all.filter((o) => o.ticket !== null && o.ticket !== undefined && inKitchen(o)), byAge);
  }

  _row(o) {
    const label = dishLabel(o);
    const step =
      o.status === "ordered"
        ? el("button", {
            class: "secondary",
            "data-needs-online": true,
            "aria-label": t("kitchen.startFor", { dish: label, table: o.table }),
            text: t("kitchen.start"),
            onclick: (e) => dishStep(this.conn, e.currentTarget, o, "cooking"),
          })
        : null;
    return el(
      "li",
      { "data-order": o.id },
      el("span", { class: "dish" }, label),
      el("span", { class: "table-tag" }, o.table),
      el("span", { class: "waiting muted", "data-ordered-at": o.ordered_at ?? "" }, this._age(o.ordered_at)),
      el(
        "span",
        { class: "row-actions" },
        step,
        el("button", {
          "data-needs-online": true,
          "aria-label": t("kitchen.readyFor", { dish: label, table: o.table }),
          text: t("kitchen.ready"),
          onclick: (e) => dishStep(this.conn, e.currentTarget, o, "ready"),
        }),
        editButtons(this.conn, o),
      ),
    );
  }

  _age(at) {
    return at ? formatDuration(this.live.clock.now() - Number(at)) : "";
  }

  _tick() {
    for (const span of document.querySelectorAll(".kitchen-list .waiting")) {
      span.textContent = this._age(span.dataset.orderedAt);
    }
  }
}
