// A table screen's calls (issue 32): three buttons — a robot to take the used plates, a waiter,
// the bill — each sending `call` `open` for this table, and what each open call of the table
// is doing now ("A waiter is on the way"), from the `calls` topic (the server shows a table
// screen its own table's calls only). A call closes when staff, or the robot sent for the
// plates, answer it, or staff cancel it: it leaves the list, and its button is free again.
//
// Pressing a kind already called is no mistake: the server merges it into the open call, and
// the screen says it is already on its way. A refusal is worded by errors.js (ui.js `act`).
//
// The topic's records are not kept by live.js: this module keeps them from the connection's
// snapshots and updates. Drawn with KeyedList: a button changes only when its call does.

import { act, el, KeyedList } from "../ui.js";
import { onLangChange, t } from "../i18n.js";

/** What a guest may call for, in the order the buttons stand. */
const KINDS = ["plates", "waiter", "bill"];
const ASK = { plates: "guest.call.plates", waiter: "guest.call.waiter", bill: "guest.call.bill" };
const AGAIN = { plates: "guest.call.platesAgain", waiter: "guest.call.waiterAgain", bill: "guest.call.billAgain" };

/** An open call as its table reads it. */
function state(call) {
  if (call.kind === "plates") return t(call.task_id !== null ? "guest.call.platesRobot" : "guest.call.platesStaff");
  return t(call.kind === "bill" ? "guest.call.billComing" : "guest.call.waiterComing");
}

const open = (call) => call.answered_at === null && call.cancelled_at === null;

export class TableCalls {
  /** `root`: the page's calls section (table.html), its buttons, states and words inside. */
  constructor(conn, table, root) {
    this.conn = conn;
    this.table = table;
    this.calls = new Map(); // id -> the open call
    this.said = root.querySelector(".call-said");
    this.buttons = new KeyedList(root.querySelector(".call-buttons"), {
      key: (kind) => kind,
      signature: (kind) => [kind, this.openOf(kind) !== null],
      build: (kind) => this._button(kind),
      lostFocus: (kind) => kind, // its request disabled it: the keyboard stays on it
    });
    this.states = new KeyedList(root.querySelector(".call-states"), {
      key: (call) => call.id,
      signature: (call) => [call.kind, call.task_id !== null],
      build: (call) => el("li", { "data-kind": call.kind }, state(call)),
    });
    conn.addEventListener("snapshot", (e) => {
      const calls = e.detail.data.calls;
      if (!Array.isArray(calls)) return;
      this.calls.clear();
      for (const call of calls) this._put(call);
      this.render();
    });
    conn.addEventListener("update", (e) => {
      if (e.detail.topic !== "calls") return;
      this._put(e.detail.data);
      this.render();
    });
    onLangChange(() => {
      this.buttons.invalidate();
      this.states.invalidate();
      this.said.textContent = this.said.dataset.kind ? t(AGAIN[this.said.dataset.kind]) : "";
      this.render();
    });
    this.render();
  }

  /** Ask for this table's calls along with the page's other topics. */
  start() {
    this.conn.subscribe(["calls"]);
  }

  /** This table's open call of `kind`, or null. */
  openOf(kind) {
    for (const call of this.calls.values()) if (call.kind === kind) return call;
    return null;
  }

  _put(call) {
    if (!call || call.table !== this.table) return;
    if (open(call)) this.calls.set(call.id, call);
    else this.calls.delete(call.id);
  }

  render() {
    this.buttons.update(KINDS);
    this.states.update([...this.calls.values()].sort((a, b) => a.opened_at - b.opened_at));
    // "Already on its way" lasts as long as the call it speaks of.
    if (this.said.dataset.kind && !this.openOf(this.said.dataset.kind)) this._say(null);
  }

  _say(kind) {
    if (kind) this.said.dataset.kind = kind;
    else delete this.said.dataset.kind;
    this.said.textContent = kind ? t(AGAIN[kind]) : "";
  }

  /** A kind's button, in a slot of its own (KeyedList gives the focus back inside a row). */
  _button(kind) {
    const called = this.openOf(kind) !== null;
    const button = el(
      "button",
      {
        type: "button",
        class: `call-button${called ? " called" : ""}`,
        "data-kind": kind,
        "data-called": String(called),
        "data-focus-key": kind,
        onclick: (e) => this.press(e.currentTarget, kind),
      },
      el("span", { class: "call-ask" }, t(ASK[kind])),
      called ? el("span", { class: "call-mark" }, t("guest.call.called")) : null,
    );
    return el("div", { class: "call-slot" }, button);
  }

  /** A guest pressed `kind`: open the call, or hear that it is already on its way. */
  async press(button, kind) {
    const reply = await act(button, () =>
      this.conn.request({ clientmsg: "call", action: "open", table: this.table, kind }),
    );
    if (!reply) return;
    this._put(reply.call); // drawn now; the topic's update brings the same record
    this._say(reply.merged ? kind : null);
    this.render();
  }
}
