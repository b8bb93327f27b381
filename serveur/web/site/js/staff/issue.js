// Issue task (the report's Figures A7-A8), the pass as staff run it: robots loading at the pass
// with their trays and Go, the dishes ready at the pass, a virtual cart and "Send" which makes
// ONE `create task` (the server groups the cart by table into trips), the dishes that came back
// (send again or void), and the tables no robot is sent to until someone clears them.
// The cart's key is made on the client, so a resend after a dropped connection cannot
// dispatch the same dishes twice. A dish whose table is a stop of a trip still at the pass (queued,
// or its robot loading) goes on that trip instead (`create task` with `task`), as a waiter would
// put the plate on the robot being loaded; the row and its table's button say so beforehand.
// Staff may choose a dish's tray in the cart (cartrays.js): the cart then leaves as one trip,
// with `trays`, and joins no trip at the pass.

import { act, byName, el, formatDuration, KeyedList, newKey, toast } from "../ui.js";
import { onLangChange, t } from "../i18n.js";
import { dishLabel, dishStep, editButtons, goButton, trayList, traySignature, voidDish } from "./dishes.js";
import { blockWords, technicalNote } from "./trouble.js";
import { keep, kept } from "../keep.js";
import { CartTrays } from "./cartrays.js";
import { tripKind } from "./trips.js";
import { TripList } from "./triplist.js";

const CART_KEY = "serveur.keep.cart"; // the cart and its key, kept across a reload (keep.js)

/** What a row shows of the trip its dishes would go on: redrawn only when that changes. */
function tripSignature(trip) {
  return trip ? [trip.id, trip.robot] : null;
}

export class IssuePanel {
  constructor(root, conn, live) {
    this.conn = conn;
    this.live = live;
    // Order ids, in the order they were added, and the cart's key: kept across a reload (a key
    // names one cart's content, so a cart sent just before the reload is not sent twice).
    const saved = kept(CART_KEY);
    const ok = saved && Array.isArray(saved.ids) && saved.ids.every(Number.isInteger) && typeof saved.key === "string";
    this.cart = ok ? saved.ids : [];
    this.key = ok ? saved.key : newKey("cart");
    // The trays staff chose in the cart: a new choice is a new cart (its key names the trays).
    this.trays = new CartTrays(live, (renew, focusId) => {
      if (renew) {
        this.key = newKey("cart");
        this._keepCart();
      }
      this._renderCart();
      const row = focusId === undefined ? null : this.cartRows.node(focusId);
      if (row && (!document.activeElement || document.activeElement === document.body)) row.querySelector(".cart-dish")?.focus();
    });
    if (ok) this.trays.load(saved.trays);
    this.ordersSeen = false; // the orders snapshot came: the cart can be checked against it
    this.sending = new Set(); // ids of a cart being sent: their leaving "pending" is expected
    this.atPass = new Map(); // table -> the trip still at the pass that serves it (render's)
    this.pendingBody = el("tbody");
    // One tap sends what is ready: everything, or one table's dishes (no cart on the way).
    this.sendAllBtn = el("button", { class: "primary", "data-needs-online": true, onclick: (e) => this._sendNow(e.currentTarget, this._ready(this._pending())) });
    this.tableSends = el("div", { class: "send-tables", role: "group", "data-i18n-aria-label": "issue.sendTables" });
    this.sendBar = el("div", { class: "send-ready" }, this.sendAllBtn, this.tableSends);
    this.cartList = el("ul", { class: "cart-list", "data-i18n-aria-label": "issue.cart" });
    this.sendBtn = el("button", { class: "primary big", "data-needs-online": true, onclick: () => this._send() });
    this.trips = new TripList(live);
    this.loadingList = el("ul", { class: "loading-list", "data-i18n-aria-label": "loading.atPass" });
    this.returnedList = el("ul", { class: "dish-list", "data-i18n-aria-label": "returned.title" });
    this.blockedList = el("ul", { class: "dish-list", "data-i18n-aria-label": "blocks.title" });
    this.loadingCard = el(
      "section",
      { class: "card loading-card", "aria-labelledby": "loading-title" },
      el("h2", { id: "loading-title", "data-i18n": "loading.atPass" }),
      this.loadingList,
    );
    this.returnedCard = el(
      "section",
      { class: "card returned-card", "aria-labelledby": "returned-title" },
      el("h2", { id: "returned-title", "data-i18n": "returned.title" }),
      el("p", { class: "muted", "data-i18n": "returned.note" }),
      this.returnedList,
    );
    this.blockedCard = el(
      "section",
      { class: "card blocked-card", "aria-labelledby": "blocked-title" },
      el("h2", { id: "blocked-title", "data-i18n": "blocks.title" }),
      this.blockedList,
    );
    root.append(
      el(
        "div",
        { class: "issue-grid" },
        el(
          "div",
          { class: "issue-main" },
          this.loadingCard,
          el(
            "section",
            { class: "card", "aria-labelledby": "pending-title" },
            el("h2", { id: "pending-title", "data-i18n": "issue.pending" }),
            this.sendBar,
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
          this.returnedCard,
          this.blockedCard,
        ),
        el(
          "section",
          { class: "card cart", "aria-labelledby": "cart-title" },
          el("h2", { id: "cart-title", "data-i18n": "issue.cart" }),
          this.cartList,
          this.trays.bar,
          el("div", { class: "cart-actions" }, el("button", { class: "secondary", onclick: () => this._clear(), "data-i18n": "issue.emptyCart" }), this.sendBtn),
          el("h2", { id: "trips-title", "data-i18n": "issue.trips" }),
          this.trips.list,
        ),
      ),
    );
    this.pendingRows = new KeyedList(this.pendingBody, {
      key: (o) => o.id,
      signature: (o) => [
        dishLabel(o),
        o.table,
        o.ready_at,
        o.status,
        this.live.blocks.get(o.table)?.robot ?? null,
        this.live.blocks.has(o.table),
        tripSignature(this.atPass.get(o.table)),
      ],
      build: (o) => this._pendingRow(o),
      empty: () => el("tr", {}, el("td", { colspan: 4, class: "muted" }, this._pending().length ? t("issue.allInCart") : t("issue.noneWaiting"))),
    });
    this.tableSendRows = new KeyedList(this.tableSends, {
      key: ([table]) => table,
      signature: ([table, ids]) => [ids.length, tripSignature(this.atPass.get(table))],
      build: ([table, ids]) => this._tableSend(table, ids.length),
    });
    this.loadingRows = new KeyedList(this.loadingList, {
      key: (r) => r.name,
      signature: (r) => [r.current_task, traySignature(this.live, r.current_task)],
      build: (r) => this._loadingRow(r),
      empty: () => el("li", { class: "muted" }, t("loading.none")),
    });
    this.returnedRows = new KeyedList(this.returnedList, {
      key: (o) => o.id,
      signature: (o) => [dishLabel(o), o.table, o.status],
      build: (o) => this._returnedRow(o),
    });
    this.blockedRows = new KeyedList(this.blockedList, {
      key: (b) => b.table,
      signature: (b) => [b.reason, b.robot],
      build: (b) => this._blockedRow(b),
    });
    this.cartRows = new KeyedList(this.cartList, {
      key: (o) => o.id,
      signature: (o) => [dishLabel(o), o.table, this.trays.signature(o)],
      build: (o) => this._cartRow(o),
      empty: () => el("li", { class: "muted" }, t("issue.cartEmpty")),
    });
    live.addEventListener("change", (e) => {
      if (e.detail.topic === "orders") this.ordersSeen = true;
      if (["orders", "tasks", "robots", "blocks"].includes(e.detail.topic)) this.render();
    });
    // Waiting times tick; only their text changes.
    setInterval(() => this._tick(), 1000);
    onLangChange(() => {
      this.trays.renderBar(true);
      for (const list of [this.pendingRows, this.tableSendRows, this.loadingRows, this.returnedRows, this.blockedRows, this.cartRows, this.trips.rows]) {
        list.invalidate();
      }
      this.render();
    });
    this.render();
  }

  _pending() {
    return [...this.live.orders.values()]
      .filter((o) => o.status === "pending")
      .sort((a, b) => a.ready_at - b.ready_at || a.id - b.id);
  }

  render() {
    this.atPass = this._tripsAtPass();
    const pending = this._pending();
    const pendingIds = new Set(pending.map((o) => o.id));
    // Dishes another tablet dispatched (or the kitchen withdrew) leave our cart.
    const gone = this.ordersSeen ? this.cart.filter((id) => !pendingIds.has(id)) : [];
    if (gone.length) {
      this.cart = this.cart.filter((id) => pendingIds.has(id));
      this.trays.keepOnly(this.cart);
      this.key = newKey("cart");
      const surprising = gone.filter((id) => !this.sending.has(id)).length;
      if (surprising) toast(t("issue.leftCart", { count: surprising }));
      this._keepCart();
    }
    const inCart = new Set(this.cart);
    this.pendingRows.update(pending.filter((o) => !inCart.has(o.id)));
    this._renderSendBar(pending);
    const loading = [...this.live.robots.values()].filter((r) => r.status === "Loading").sort((a, b) => byName(a.name, b.name));
    this.loadingRows.update(loading);
    const returned = [...this.live.orders.values()]
      .filter((o) => o.status === "returned")
      .sort((a, b) => (a.returned_at ?? 0) - (b.returned_at ?? 0) || a.id - b.id);
    this.returnedRows.update(returned);
    this.returnedCard.hidden = !returned.length;
    const blocked = [...this.live.blocks.values()].sort((a, b) => byName(a.table, b.table));
    this.blockedRows.update(blocked);
    this.blockedCard.hidden = !blocked.length;
    this._renderCart();
    this.trips.render();
  }

  _pendingRow(o) {
    const block = this.live.blocks.get(o.table);
    const label = dishLabel(o);
    return el(
      "tr",
      { "data-order": o.id, class: block ? "blocked" : "" },
      el("td", {}, label),
      el(
        "td",
        {},
        o.table,
        block ? el("span", { class: "why-waiting" }, t("blocks.dishWaits", { reason: blockWords(block) })) : null,
        this._goesWith(o.table),
      ),
      el("td", { class: "waiting", "data-ready-at": o.ready_at }, this._waiting(o.ready_at)),
      el(
        "td",
        { class: "row-actions" },
        el("button", {
          "aria-label": t("issue.addFor", { dish: label, table: o.table }),
          disabled: Boolean(block),
          onclick: () => this._setCart([...this.cart, o.id]),
          text: t("issue.add"),
        }),
        editButtons(this.conn, o),
      ),
    );
  }

  _loadingRow(robot) {
    return el(
      "li",
      { class: "loading", "data-robot": robot.name },
      el("span", { class: "loading-title" }, t("loading.robot", { name: robot.name })),
      trayList(this.live, robot.current_task),
      goButton(this.conn, this.live, robot.name),
    );
  }

  _returnedRow(o) {
    const label = dishLabel(o);
    return el(
      "li",
      { "data-order": o.id },
      el("span", { class: "dish" }, label),
      el("span", { class: "table-tag" }, o.table),
      el("button", {
        "data-needs-online": true,
        "aria-label": t("returned.againFor", { dish: label, table: o.table }),
        text: t("returned.again"),
        onclick: (e) => this._sendAgain(e.currentTarget, o),
      }),
      el("button", {
        class: "danger",
        "data-needs-online": true,
        "aria-label": t("dish.voidFor", { dish: label, table: o.table }),
        text: t("dish.void"),
        onclick: (e) => voidDish(this.conn, e.currentTarget, o),
      }),
    );
  }

  _blockedRow(b) {
    return el(
      "li",
      { "data-table": b.table },
      el("span", { class: "table-tag" }, b.table),
      el("span", { class: "dish" }, blockWords(b)),
      technicalNote(b.reason),
      el("button", {
        "data-needs-online": true,
        "aria-label": t("blocks.clearFor", { table: b.table }),
        text: t("blocks.clear"),
        onclick: (e) => act(e.currentTarget, () => this.conn.request({ clientmsg: "clear", table: b.table })),
      }),
    );
  }

  /**
   * "Send again" sends: the dish goes back to the pass (ready) and leaves on a trip in the same
   * press. For a blocked table it stays at the pass, said by the server's refusal.
   */
  async _sendAgain(button, order) {
    const back = await dishStep(this.conn, button, order, "ready");
    if (!back) return;
    if (this.live.blocks.has(order.table)) return; // waits at the pass, the row says why
    await this._dispatch(button, [order.id], newKey("again"));
  }

  /** The ids of `pending`'s dishes a robot may take now (not for a blocked table). */
  _ready(pending) {
    return pending.filter((o) => !this.live.blocks.has(o.table)).map((o) => o.id);
  }

  /**
   * The trips still at the pass, by the tables they serve: queued, or taken by a robot that is
   * Loading. A dish for one of those tables goes on that trip (the robot being loaded first).
   */
  _tripsAtPass() {
    const loading = (trip) => trip.status === "active" && Boolean(trip.robot) && this.live.robots.get(trip.robot)?.status === "Loading";
    const trips = [...this.live.tasks.values()]
      .filter((trip) => tripKind(trip) === "delivery" && (trip.status === "queued" || loading(trip)))
      .sort((a, b) => Number(loading(b)) - Number(loading(a)) || a.id - b.id);
    const byTable = new Map();
    for (const trip of trips) {
      for (const stop of trip.stops) if (!byTable.has(stop.table)) byTable.set(stop.table, trip);
    }
    return byTable;
  }

  /** Under a pending dish's table: the trip it will go on when sent, if one is at the pass. */
  _goesWith(table) {
    const trip = this.atPass.get(table);
    if (!trip) return null;
    const words = trip.robot ? t("issue.goesOnTrays", { robot: trip.robot }) : t("issue.goesOnTrip", { id: trip.id });
    return el("div", { class: "muted" }, words);
  }

  /** One table's send button: "Add T3 to r1" when its dishes would go on a trip at the pass. */
  _tableSend(table, count) {
    const trip = this.atPass.get(table);
    const dishes = t("count.dishes", { count });
    let label = t("issue.sendTableFor", { table, dishes });
    let text = t("issue.sendTable", { table, count });
    if (trip && trip.robot) {
      label = t("issue.addTableRobotFor", { table, dishes, robot: trip.robot });
      text = t("issue.addTableRobot", { table, count, robot: trip.robot });
    } else if (trip) {
      label = t("issue.addTableTripFor", { table, dishes, id: trip.id });
      text = t("issue.addTableTrip", { table, count, id: trip.id });
    }
    return el("button", {
      class: "secondary",
      "data-needs-online": true,
      "aria-label": label,
      onclick: (e) => this._sendNow(e.currentTarget, this._ready(this._pending().filter((o) => o.table === table))),
      text,
    });
  }

  /** "Send all ready" and one button per table, from the dishes `render` found pending. */
  _renderSendBar(pending) {
    const ready = this._ready(pending);
    const byTable = new Map();
    for (const o of pending) {
      if (this.live.blocks.has(o.table)) continue;
      if (!byTable.has(o.table)) byTable.set(o.table, []);
      byTable.get(o.table).push(o.id);
    }
    this.sendBar.hidden = !ready.length;
    this.sendAllBtn.textContent = t("issue.sendAll", {
      dishes: t("count.dishes", { count: ready.length }),
      tables: t("count.tables", { count: byTable.size }),
    });
    // Per table only when there is more than one table (else it is the same as "all").
    this.tableSendRows.update(byTable.size > 1 ? [...byTable].sort((a, b) => byName(a[0], b[0])) : []);
  }

  /** Send `orders` at once (under its own key): what "Send" does with a cart. */
  async _sendNow(button, orders) {
    if (!orders.length) return;
    await this._dispatch(button, orders, newKey("send"));
  }

  _renderCart() {
    const items = this.cart.map((id) => this.live.orders.get(id)).filter(Boolean);
    this.cartRows.update(items);
    const tables = new Set(items.map((o) => o.table));
    this.sendBtn.textContent = items.length
      ? t("issue.sendCount", {
          dishes: t("count.dishes", { count: items.length }),
          tables: t("count.tables", { count: tables.size }),
        })
      : t("issue.send");
    this.sendBtn.disabled = !items.length;
    this.trays.renderBar();
  }

  _cartRow(o) {
    return el(
      "li",
      {},
      this.trays.dishButton(o),
      el("span", { class: "table-tag" }, o.table),
      el("button", {
        class: "secondary",
        "aria-label": t("issue.removeFor", { dish: dishLabel(o), table: o.table }),
        onclick: () => this._setCart(this.cart.filter((x) => x !== o.id)),
        text: t("issue.remove"),
      }),
    );
  }

  _setCart(ids) {
    this.cart = ids;
    this.trays.keepOnly(ids);
    this.key = newKey("cart"); // new content, new key: a key names exactly one cart
    this._keepCart();
    this.render();
  }

  _keepCart() {
    keep(CART_KEY, this.cart.length ? { ids: this.cart, key: this.key, trays: this.trays.saved() } : null);
  }

  _clear() {
    this._setCart([]);
  }

  async _send() {
    const orders = [...this.cart];
    if (!orders.length) return;
    const reply = await this._dispatch(this.sendBtn, orders, this.key, this.trays.request(orders));
    this._renderCart(); // act() re-enabled the button whatever the cart holds now
    if (reply && this.cart.join() === orders.join()) this._setCart([]);
  }

  /**
   * Send `orders` under `key`: the dishes for a table a trip still at the pass serves go on that
   * trip (one `create task` with `task` per trip, key `key-<trip>`), the others in one
   * `create task` (the server groups them by table into trips), as do those whose trip left
   * meanwhile (`stale`: Go was pressed). One toast says where the dishes went. The reply of the
   * whole (its `tasks`: the new trips), or null after an error was shown.
   */
  async _dispatch(button, orders, key, trays = null) {
    // Trays chosen: the cart is one trip of its own (a trip at the pass keeps its plan).
    const atPass = trays ? new Map() : this._tripsAtPass();
    const joins = new Map(); // trip id -> {trip, ids}
    const cart = [];
    for (const id of orders) {
      const trip = atPass.get(this.live.orders.get(id)?.table);
      if (!trip) cart.push(id);
      else if (joins.has(trip.id)) joins.get(trip.id).ids.push(id);
      else joins.set(trip.id, { trip, ids: [id] });
    }
    const words = []; // what happened, in a waiter's words: one toast
    orders.forEach((id) => this.sending.add(id));
    const reply = await act(button, async () => {
      for (const { trip, ids } of joins.values()) {
        const msg = { clientmsg: "create", type: "task", task: trip.id, orders: ids, key: `${key}-${trip.id}` };
        try {
          const added = await this.conn.request(msg, { resend: true });
          words.push(this._joinedWords(added.tasks[0] ?? trip, ids));
        } catch (err) {
          if (err.code !== "stale") throw err;
          cart.push(...ids); // the robot left with its trip: these make a trip of their own
        }
      }
      if (!cart.length) return { tasks: [] };
      const msg = { clientmsg: "create", type: "task", orders: cart, key };
      if (trays) msg.trays = trays;
      return this.conn.request(msg, { resend: true });
    });
    orders.forEach((id) => this.sending.delete(id));
    if (reply && reply.tasks.length) {
      const trips = reply.tasks.map((task) => task.stops.map((s) => s.table).join(", "));
      words.push(t("issue.sent", { trips: t("count.trips", { count: reply.tasks.length }), tables: trips.join(" | ") }));
    }
    if (words.length) toast(words.join(" · "));
    return reply;
  }

  /** "Added to r1's trays: T3": where the dishes `ids` went on `trip`, in a waiter's words. */
  _joinedWords(trip, ids) {
    const tables = [...new Set(ids.map((id) => this.live.orders.get(id)?.table).filter(Boolean))].sort(byName).join(", ");
    return trip.robot ? t("issue.addedToTrays", { robot: trip.robot, tables }) : t("issue.addedToTrip", { id: trip.id, tables });
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
