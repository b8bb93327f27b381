// Issue task (the report's Figures A7-A8): the dishes waiting at the pass, a virtual cart,
// and "Send" which makes ONE `create task`; the server groups the cart by table into trips.
// The cart's key is made on the client, so a resend after a dropped connection cannot
// dispatch the same dishes twice.

import { act, el, formatDuration, newKey, toast } from "../ui.js";
import { onLangChange, t } from "../i18n.js";

function taskStatus(status) {
  return status === "queued" ? t("task.queued") : status === "active" ? t("task.active") : status;
}

export class IssuePanel {
  constructor(root, conn, live) {
    this.conn = conn;
    this.live = live;
    this.cart = []; // order ids, in the order they were added
    this.key = newKey("cart");
    this.sending = new Set(); // ids of a cart being sent: their leaving "pending" is expected
    this.pendingBody = el("tbody");
    this.cartList = el("ul", { class: "cart-list", "data-i18n-aria-label": "issue.cart" });
    this.sendBtn = el("button", { class: "primary big", onclick: () => this._send() });
    this.trips = el("ul", { class: "trips", "data-i18n-aria-label": "issue.trips" });
    root.append(
      el(
        "div",
        { class: "issue-grid" },
        el(
          "section",
          { class: "card", "aria-labelledby": "pending-title" },
          el("h2", { id: "pending-title", "data-i18n": "issue.pending" }),
          el(
            "table",
            { class: "pending", "aria-labelledby": "pending-title" },
            el(
              "thead",
              {},
              el(
                "tr",
                {},
                ["issue.col.dish", "issue.col.table", "issue.col.waiting"].map((k) => el("th", { scope: "col", "data-i18n": k })),
                el("th", { scope: "col" }),
              ),
            ),
            this.pendingBody,
          ),
        ),
        el(
          "section",
          { class: "card cart", "aria-labelledby": "cart-title" },
          el("h2", { id: "cart-title", "data-i18n": "issue.cart" }),
          this.cartList,
          el("div", { class: "cart-actions" }, el("button", { class: "secondary", onclick: () => this._clear(), "data-i18n": "issue.emptyCart" }), this.sendBtn),
          el("h2", { id: "trips-title", "data-i18n": "issue.trips" }),
          this.trips,
        ),
      ),
    );
    live.addEventListener("change", (e) => {
      if (["orders", "tasks", "robots"].includes(e.detail.topic)) this.render();
    });
    // Waiting times tick; only their text changes.
    setInterval(() => this._tick(), 1000);
    onLangChange(() => this.render());
    this.render();
  }

  _pending() {
    return [...this.live.orders.values()]
      .filter((o) => o.status === "pending")
      .sort((a, b) => a.ready_at - b.ready_at || a.id - b.id);
  }

  render() {
    const pending = this._pending();
    const pendingIds = new Set(pending.map((o) => o.id));
    // Dishes another tablet dispatched (or the kitchen withdrew) leave our cart.
    const gone = this.cart.filter((id) => !pendingIds.has(id));
    if (gone.length) {
      this.cart = this.cart.filter((id) => pendingIds.has(id));
      this.key = newKey("cart");
      const surprising = gone.filter((id) => !this.sending.has(id)).length;
      if (surprising) toast(t("issue.leftCart", { count: surprising }));
    }
    const inCart = new Set(this.cart);
    const rows = pending
      .filter((o) => !inCart.has(o.id))
      .map((o) =>
        el(
          "tr",
          { "data-order": o.id },
          el("td", {}, o.dish),
          el("td", {}, o.table),
          el("td", { class: "waiting", "data-ready-at": o.ready_at }, this._waiting(o.ready_at)),
          el(
            "td",
            {},
            el("button", {
              "aria-label": t("issue.addFor", { dish: o.dish, table: o.table }),
              onclick: () => this._setCart([...this.cart, o.id]),
              text: t("issue.add"),
            }),
          ),
        ),
      );
    if (!rows.length) {
      rows.push(el("tr", {}, el("td", { colspan: 4, class: "muted" }, pending.length ? t("issue.allInCart") : t("issue.noneWaiting"))));
    }
    this.pendingBody.replaceChildren(...rows);
    this._renderCart();
    this._renderTrips();
  }

  _renderCart() {
    const items = this.cart.map((id) => this.live.orders.get(id)).filter(Boolean);
    this.cartList.replaceChildren(
      ...items.map((o) =>
        el(
          "li",
          {},
          el("span", { class: "dish" }, o.dish),
          el("span", { class: "table-tag" }, o.table),
          el("button", {
            class: "secondary",
            "aria-label": t("issue.removeFor", { dish: o.dish, table: o.table }),
            onclick: () => this._setCart(this.cart.filter((x) => x !== o.id)),
            text: t("issue.remove"),
          }),
        ),
      ),
    );
    if (!items.length) this.cartList.append(el("li", { class: "muted" }, t("issue.cartEmpty")));
    const tables = new Set(items.map((o) => o.table));
    this.sendBtn.textContent = items.length
      ? t("issue.sendCount", {
          dishes: t("count.dishes", { count: items.length }),
          tables: t("count.tables", { count: tables.size }),
        })
      : t("issue.send");
    this.sendBtn.disabled = !items.length;
  }

  _renderTrips() {
    const open = [...this.live.tasks.values()].filter((t) => t.status === "queued" || t.status === "active");
    this.trips.replaceChildren(
      ...open.map((trip) =>
        el(
          "li",
          {},
          (trip.robot ? t("issue.tripRobot", { id: trip.id, status: taskStatus(trip.status), robot: trip.robot }) : t("issue.trip", { id: trip.id, status: taskStatus(trip.status) })) + " · ",
          trip.stops.map((s) => `${s.table} (${s.orders.length})`).join(" → "),
        ),
      ),
    );
    if (!open.length) this.trips.append(el("li", { class: "muted" }, t("issue.noTrips")));
  }

  _setCart(ids) {
    this.cart = ids;
    this.key = newKey("cart"); // new content, new key: a key names exactly one cart
    this.render();
  }

  _clear() {
    this._setCart([]);
  }

  async _send() {
    const orders = [...this.cart];
    if (!orders.length) return;
    const msg = { clientmsg: "create", type: "task", orders, key: this.key };
    orders.forEach((id) => this.sending.add(id));
    const reply = await act(this.sendBtn, () => this.conn.request(msg, { resend: true }));
    orders.forEach((id) => this.sending.delete(id));
    this._renderCart(); // act() re-enabled the button whatever the cart holds now
    if (!reply) return;
    const trips = reply.tasks.map((task) => task.stops.map((s) => s.table).join(", "));
    toast(t("issue.sent", { trips: t("count.trips", { count: reply.tasks.length }), tables: trips.join(" | ") }));
    if (this.cart.join() === orders.join()) this._setCart([]);
  }

  _waiting(readyAt) {
    return formatDuration(this.live.clock.now() - readyAt);
  }

  _tick() {
    for (const cell of this.pendingBody.querySelectorAll("td.waiting")) {
      cell.textContent = this._waiting(Number(cell.dataset.readyAt));
    }
  }
}
