// Calls (every staff console): what guests asked for from their tables — a table's screen, a
// Wi-Fi button, or staff for a guest (the `calls` topic: the open calls, then each call as it
// changes; an answered or cancelled one leaves the list). Each row: the table, what it wants
// ("Plates", "Waiter", "Bill"), how long ago, where the call came from, a robot on its way for
// the plates; Answer (someone went) and Cancel. Calls nobody answered in time (escalated_at)
// come first and are marked; they also raise a `call_waiting` alert (alerts.js sounds it).
//
// A new call rings once on this device (ring.js: the header's sound choice; a call that came
// while the browser held the sound back rings once the page is touched), and the Calls tab
// shows how many wait, so a waiter on another tab sees them.

import { act, byName, el, formatDuration, KeyedList, toast } from "../ui.js";
import { onLangChange, t } from "../i18n.js";
import { keep, kept } from "../keep.js";
import { consoleSound } from "./ring.js";
import { kindWords, sourceWords, wantWords } from "./callwords.js";

const HEARD_KEY = "serveur.keep.callsHeard"; // the calls this device rang for, across a reload
const HEARD_KEPT = 100;
// Two rising tones, a doorbell: a guest asks (an alert's chime falls instead).
const CALL_NOTES = [784, 1047];

/** A call nobody answered or cancelled yet. */
function isOpen(call) {
  return call.answered_at == null && call.cancelled_at == null;
}

export class CallsPanel {
  /** `root`: the Calls tab's panel; `tab`: its tab button, which shows the count. */
  constructor(root, tab, conn, live) {
    this.conn = conn;
    this.live = live;
    this.calls = new Map(); // id -> open call
    const heard = kept(HEARD_KEY, []);
    this.heard = new Set(Array.isArray(heard) ? heard.filter(Number.isInteger) : []);
    this.chime = consoleSound.chime(CALL_NOTES);
    this.owed = false; // a new call came while the sound was held back: ring once it runs
    this.chimes = 0;
    if (this.chime.ctx) {
      this.chime.ctx.addEventListener("statechange", () => {
        if (this.owed && this.chime.ctx.state === "running") this._ring();
      });
    }
    this.number = el("span", { class: "tab-count-n", "aria-hidden": "true" });
    this.spoken = el("span", { class: "visually-hidden" });
    this.count = el("span", { class: "tab-count", "data-testid": "calls-count", hidden: true }, this.number, this.spoken);
    tab.append(" ", this.count);
    this.list = el("ul", { class: "call-list", "data-i18n-aria-label": "calls.title" });
    root.append(
      el(
        "section",
        { class: "card calls-card", "aria-labelledby": "calls-title" },
        el("h2", { id: "calls-title", "data-i18n": "calls.title" }),
        el("p", { class: "muted", "data-i18n": "calls.note" }),
        this.list,
      ),
    );
    this.rows = new KeyedList(this.list, {
      key: (c) => c.id,
      signature: (c) => [c.table, c.kind, c.source, c.presses, c.escalated_at, this._robotWords(c)],
      build: (c) => this._row(c),
      empty: () => el("li", { class: "muted" }, t("calls.none")),
    });
    conn.addEventListener("snapshot", (e) => {
      const snap = e.detail.data && e.detail.data.calls;
      if (!Array.isArray(snap)) return;
      this.calls.clear(); // newer than any update before it
      for (const call of snap) this._put(call);
      this.render();
    });
    conn.addEventListener("update", (e) => {
      if (e.detail.topic !== "calls") return;
      this._put(e.detail.data);
      this.render();
    });
    // A robot taking a plates call's trip, or leaving with it: the row says so.
    live.addEventListener("change", (e) => ["tasks", "robots"].includes(e.detail.topic) && this.render());
    setInterval(() => this._tick(), 1000);
    onLangChange(() => {
      this.rows.invalidate();
      this.render();
    });
    conn.subscribe(["calls"]);
    this.render();
  }

  _put(call) {
    if (!call || !Number.isInteger(call.id)) return;
    if (isOpen(call)) this.calls.set(call.id, call);
    else this.calls.delete(call.id);
    this.live.clock.saw(call.answered_at ?? call.cancelled_at ?? call.escalated_at ?? call.opened_at);
  }

  /** Escalated first (the longest waiting first), then the others, oldest first. */
  _sorted() {
    return [...this.calls.values()].sort(
      (a, b) =>
        Number(b.escalated_at != null) - Number(a.escalated_at != null) ||
        a.opened_at - b.opened_at ||
        byName(a.table, b.table) ||
        a.id - b.id,
    );
  }

  render() {
    const calls = this._sorted();
    this.rows.update(calls);
    this._badge(calls);
    let fresh = false;
    for (const call of calls) {
      if (this.heard.has(call.id)) continue;
      this.heard.add(call.id);
      fresh = true;
    }
    if (fresh) {
      keep(HEARD_KEY, [...this.heard].slice(-HEARD_KEPT));
      if (!consoleSound.muted) this._ring();
    }
  }

  /** One chime (data-chimes on the list says how many this page rang). */
  _ring() {
    this.owed = !this.chime.play();
    if (this.owed) return;
    this.chimes += 1;
    this.list.dataset.chimes = String(this.chimes);
  }

  _badge(calls) {
    const n = calls.length;
    this.count.hidden = !n;
    this.count.classList.toggle("urgent", calls.some((c) => c.escalated_at != null));
    this.number.textContent = String(n);
    this.spoken.textContent = t("calls.badge", { count: n });
  }

  /** A plates call: the robot sent for it, in words; null for any other call. */
  _robotWords(call) {
    if (call.kind !== "plates") return null;
    if (call.task_id == null) return t("calls.noRobot");
    const task = this.live.tasks.get(call.task_id);
    if (!task || task.status === "done" || task.status === "cancelled") return null;
    return task.robot ? t("calls.robotComing", { robot: task.robot }) : t("calls.robotSoon");
  }

  _ago(call) {
    return t("calls.ago", { time: formatDuration(this.live.clock.now() - call.opened_at) });
  }

  _row(call) {
    const what = wantWords(call);
    const escalated = call.escalated_at != null;
    const robot = this._robotWords(call);
    const from = sourceWords(call.source);
    return el(
      "li",
      { class: escalated ? "call escalated" : "call", "data-call": call.id, "data-table": call.table },
      el("span", { class: "table-tag call-table" }, call.table),
      el("strong", { class: "call-kind" }, kindWords(call.kind)),
      escalated ? el("span", { class: "call-urgent" }, t("calls.escalated")) : null,
      el("span", { class: "call-ago", "data-opened": call.opened_at }, this._ago(call)),
      el("span", { class: "call-from muted" }, call.presses > 1 ? t("calls.fromPressed", { from, count: call.presses }) : from),
      robot ? el("span", { class: "call-robot" }, robot) : null,
      el(
        "div",
        { class: "row-actions" },
        el("button", {
          class: "primary",
          "data-needs-online": true,
          "data-focus-key": "answer",
          "aria-label": t("calls.answerFor", { what }),
          text: t("calls.answer"),
          onclick: (e) => this._close(e.currentTarget, call, "answer"),
        }),
        el("button", {
          class: "secondary",
          "data-needs-online": true,
          "data-focus-key": "cancel",
          "aria-label": t("calls.cancelFor", { what }),
          text: t("calls.cancel"),
          onclick: (e) => this._close(e.currentTarget, call, "cancel"),
        }),
      ),
    );
  }

  async _close(button, call, action) {
    const reply = await act(button, () => this.conn.request({ clientmsg: "call", action, call: call.id }));
    if (!reply) return;
    if (reply.call) this._put(reply.call);
    this.render();
    // The row is gone: the keyboard goes on to the next call, or to the list.
    if (!document.activeElement || document.activeElement === document.body) {
      const next = this.list.querySelector("button[data-focus-key='answer']");
      if (next) next.focus();
    }
    toast(t(action === "answer" ? "calls.answered" : "calls.cancelled", { what: wantWords(call) }));
  }

  _tick() {
    for (const span of this.list.querySelectorAll(".call-ago")) {
      const call = this.calls.get(Number(span.closest("[data-call]")?.dataset.call));
      if (call) span.textContent = this._ago(call);
    }
  }
}
