// A guest's call in a waiter's words: what the table wants ("Plates", "Waiter", "Bill"), where
// the call came from (the table's screen, a Wi-Fi button, staff), and the alert a call nobody
// answered raises (`call_waiting`, subject "T3/waiter"). The wire's kinds stay English; the
// words are the catalogs'.

import { t } from "../i18n.js";

// The keys are written whole: the i18n test reads them in the source.
const KIND = { plates: "calls.kind.plates", waiter: "calls.kind.waiter", bill: "calls.kind.bill" };
const WANTS = { plates: "calls.wants.plates", waiter: "calls.wants.waiter", bill: "calls.wants.bill" };
const WAITING = {
  plates: "alerts.kind.callWaiting.plates",
  waiter: "alerts.kind.callWaiting.waiter",
  bill: "alerts.kind.callWaiting.bill",
};

export const CALL_KINDS = Object.keys(KIND);

/** "Plates", "Waiter", "Bill". */
export function kindWords(kind) {
  return KIND[kind] ? t(KIND[kind]) : kind;
}

/** "T3 wants a waiter": the whole call as one sentence (a button's label, a toast). */
export function wantWords(call) {
  return t(WANTS[call.kind] || "calls.wants.other", { table: call.table });
}

/** "from the table's screen", "button “T7 bill”", "called by staff". */
export function sourceWords(source) {
  if (source === "table") return t("calls.from.table");
  if (typeof source === "string" && source.startsWith("button:")) return t("calls.from.button", { name: source.slice(7) });
  return t("calls.from.staff");
}

/** A `call_waiting` alert's headline from its subject "<table>/<kind>". */
export function callAlertWords(subject) {
  const at = String(subject).lastIndexOf("/");
  const table = at < 0 ? String(subject) : subject.slice(0, at);
  const kind = at < 0 ? "" : subject.slice(at + 1);
  return t(WAITING[kind] || "alerts.kind.callWaiting.other", { table });
}
