// The cart's trays (issue.js): by default the plan puts each table's dishes on a tray; staff
// may choose one instead — tap a dish in the cart, then a tray number (1 .. the site's trays),
// or "Automatic" to give it back to the plan. The choices go with the cart as `create task`'s
// `trays` (docs/protocol.md): the cart then leaves as one trip. A choice is kept with the cart
// across a reload (issue.js keeps both) and forgotten with the dish.

import { el } from "../ui.js";
import { t } from "../i18n.js";
import { dishLabel } from "./dishes.js";

const DEFAULT_TRAYS = 3; // the site's default until its settings are read

export class CartTrays {
  /** `changed(renew, focusId)`: the cart is drawn again; `renew`: a choice was made (the cart's
   *  key must change: it names the trays too); `focusId`: the dish whose row takes the keyboard
   *  back (the tray numbers are gone). */
  constructor(live, changed) {
    this.live = live;
    this.changed = changed;
    this.choice = new Map(); // order id -> tray
    this.picking = null; // the order whose tray is being chosen, or null
    this.bar = el("div", { class: "tray-bar", role: "group", "data-testid": "tray-bar", hidden: true });
    this.drawn = null; // what the bar shows now: drawn again only when that changes
  }

  /** How many trays a robot has (the site's setting). */
  count() {
    const n = this.live.settings && this.live.settings.trays;
    return Number.isInteger(n) && n > 0 ? n : DEFAULT_TRAYS;
  }

  /** The choices as kept with the cart: [[order, tray], ...]. */
  saved() {
    return [...this.choice];
  }

  /** Choices read back from the device (checked: storage is the device's). */
  load(saved) {
    this.choice.clear();
    if (!Array.isArray(saved)) return;
    for (const pair of saved) {
      if (Array.isArray(pair) && Number.isInteger(pair[0]) && Number.isInteger(pair[1]) && pair[1] >= 1 && pair[1] <= 12) {
        this.choice.set(pair[0], pair[1]);
      }
    }
  }

  /** Only the dishes still in the cart keep a choice. */
  keepOnly(ids) {
    const inCart = new Set(ids);
    for (const id of [...this.choice.keys()]) if (!inCart.has(id)) this.choice.delete(id);
    if (this.picking !== null && !inCart.has(this.picking)) this.picking = null;
  }

  clear() {
    this.choice.clear();
    this.picking = null;
  }

  /** `create task`'s trays for `ids`, or null when the plan chooses them all. */
  request(ids) {
    const trays = ids.filter((id) => this.choice.has(id)).map((id) => ({ order: id, tray: this.choice.get(id) }));
    return trays.length ? trays : null;
  }

  /** What a cart row shows of its tray: redrawn only when that changes. */
  signature(order) {
    return [this.choice.get(order.id) ?? null, this.picking === order.id, this.count()];
  }

  /** The cart row's dish, a button: tapped, the tray numbers show under the cart. */
  dishButton(order) {
    const tray = this.choice.get(order.id);
    return el(
      "button",
      {
        type: "button",
        class: "cart-dish",
        "data-focus-key": "tray",
        "aria-pressed": String(this.picking === order.id),
        onclick: () => this._pick(order.id),
      },
      el("span", { class: "dish" }, dishLabel(order)),
      " ",
      el("span", { class: tray ? "tray-tag chosen" : "tray-tag" }, tray ? t("cart.onTray", { tray }) : t("cart.autoTray")),
    );
  }

  _pick(id) {
    this.picking = this.picking === id ? null : id;
    this.changed(false);
  }

  _choose(tray) {
    const id = this.picking;
    if (id === null) return;
    if (tray === null) this.choice.delete(id);
    else this.choice.set(id, tray);
    this.picking = null;
    this.changed(true, id);
  }

  /** The tray numbers for the dish being placed (hidden when none is); `force`: new words. */
  renderBar(force = false) {
    const order = this.picking === null ? null : this.live.orders.get(this.picking);
    const label = order ? t("cart.putOn", { dish: dishLabel(order), table: order.table }) : "";
    const now = order ? this.choice.get(order.id) ?? null : null;
    const drawn = JSON.stringify([label, now, this.count()]);
    if (drawn === this.drawn && !force) return; // a button is not replaced under a finger
    this.drawn = drawn;
    this.bar.hidden = !order;
    if (!order) {
      this.bar.replaceChildren();
      return;
    }
    this.bar.setAttribute("aria-label", label);
    const numbers = Array.from({ length: this.count() }, (_, i) => i + 1).map((n) =>
      el("button", {
        type: "button",
        class: "tray-pick",
        "aria-pressed": String(now === n),
        "aria-label": t("cart.trayN", { tray: n }),
        text: String(n),
        onclick: () => this._choose(n),
      }),
    );
    const auto = el("button", {
      type: "button",
      class: "secondary",
      "aria-pressed": String(now === null),
      text: t("cart.auto"),
      onclick: () => this._choose(null),
    });
    this.bar.replaceChildren(el("span", { class: "tray-bar-label" }, label), ...numbers, auto);
    const first = this.bar.querySelector("button[aria-pressed='true']") || numbers[0];
    if (first && document.activeElement && document.activeElement.classList.contains("cart-dish")) first.focus();
  }
}
