// A table's screen: its virtual cart — dishes on the way and served (`order` {table}), plus
// the ones ready at the pass (from the `orders` topic). URL: /table/<name> or ?table=<name>.
// Refreshed whenever an order of this table changes.

import { Connection } from "./ws.js";
import { Live } from "./live.js";
import { el, showError, watchConnection } from "./ui.js";
import { onLangChange, t } from "./i18n.js";

const table = tableName();
const conn = new Connection();
const live = new Live(conn);
watchConnection(conn);
function titles() {
  document.title = t("table.docTitle", { table: table || "" });
  document.getElementById("table-title").textContent = table ? t("table.title", { table }) : t("table.noName");
}
titles();
onLangChange(() => {
  titles();
  if (loaded) render();
});

let cart = [];
let asking = null;
let loaded = false; // the orders came: "nothing ..." can be said

function tableName() {
  const parts = window.location.pathname.split("/").filter(Boolean);
  if (parts[0] === "table" && parts[1]) return decodeURIComponent(parts[1]);
  return new URLSearchParams(window.location.search).get("table");
}

async function refresh() {
  if (!table) return;
  // Coalesce bursts of updates into one request at a time, plus one more if needed after it.
  if (asking) {
    asking.again = true;
    return;
  }
  asking = { again: false };
  try {
    cart = (await conn.request({ clientmsg: "order", table }, { resend: true })).orders;
    render();
  } catch (err) {
    showError(err);
  } finally {
    const again = asking.again;
    asking = null;
    if (again) refresh();
  }
}

function items(orders, empty) {
  if (!orders.length) return [el("li", { class: "muted" }, empty)];
  return orders.map((o) => el("li", { "data-order": o.id }, el("span", { class: "dish" }, o.dish)));
}

function render() {
  const coming = cart.filter((o) => o.status === "assigned");
  const served = cart.filter((o) => o.status === "delivered");
  const atPass = [...live.orders.values()].filter((o) => o.table === table && o.status === "pending");
  document.getElementById("coming").replaceChildren(...items(coming, t("table.comingEmpty")));
  document.getElementById("served").replaceChildren(...items(served, t("table.servedEmpty")));
  document.getElementById("at-pass").replaceChildren(...items(atPass, t("table.passEmpty")));
}

live.addEventListener("change", (e) => {
  const { topic, record } = e.detail;
  if (topic !== "orders" || (record && record.table !== table)) return;
  loaded = true;
  render();
  refresh();
});
conn.subscribe(["orders"]);
conn.start();
