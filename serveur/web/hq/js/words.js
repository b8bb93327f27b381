// A site as a manager says it: connected or not (and since when it was last heard from), in
// sync or catching up, each robot in the words the site's own screens use, each open alert as
// the staff console words it. Shared by the overview's cards and a site's page.

import { el } from "./dom.js";
import { clock, count } from "./format.js";
import { has, t } from "./i18n.js";

// Each kind of alert's headline (the staff console's words), from its subject.
const ALERT_KINDS = {
  robot_error: "alert.kind.robotError",
  robot_offline: "alert.kind.robotOffline",
  low_battery: "alert.kind.lowBattery",
  waiting_at_table: "alert.kind.waitingAtTable",
  dish_waiting: "alert.kind.dishWaiting",
  table_unreachable: "alert.kind.tableUnreachable",
  zone_wait: "alert.kind.zoneWait",
  robot_lost: "alert.kind.robotLost",
  not_charging: "alert.kind.notCharging",
  ticket_unread: "alert.kind.ticketUnread",
  printer_down: "alert.kind.printerDown",
};
const CALLS = {
  plates: "alert.kind.callWaiting.plates",
  waiter: "alert.kind.callWaiting.waiter",
  bill: "alert.kind.callWaiting.bill",
};

/** "down", "up" or "unknown" (never decided yet). */
export function stateOf(site) {
  return site.state === "down" ? "down" : site.state === "up" ? "up" : "unknown";
}

/** The site's connection in words: [headline, detail]. */
export function stateWords(site, now) {
  const state = stateOf(site);
  if (state === "down") {
    const heard = site.heard_at ?? site.state_at;
    return [t("site.down"), heard ? t("site.notHeard", { time: clock(heard, now) }) : t("site.neverHeard")];
  }
  if (state === "up") return [t("site.up"), ""];
  return [t("site.unknown"), ""];
}

/** Whether the centre holds all the site has sent, in words. */
export function syncWords(site) {
  const behind = Number(site.behind) || 0;
  if (behind <= 0) return t("site.inSync");
  const key = stateOf(site) === "down" ? "site.stillToReceive" : "site.catchingUp";
  return t(key, { count: behind, n: count(behind) });
}

/** A robot status (the wire value) in the site's screens' words. */
export function statusName(status) {
  return has(`status.${status}`) ? t(`status.${status}`) : String(status);
}

export function robotItem(robot, now) {
  return el(
    "li",
    { class: "robot", "data-robot": robot.robot },
    el("span", { class: "robot-name" }, robot.robot),
    " ",
    el("span", { class: "badge", "data-status": robot.status }, statusName(robot.status)),
    " ",
    el("span", { class: "muted" }, t("robot.since", { time: clock(robot.since, now) })),
    robot.error ? el("span", { class: "robot-error" }, t("robot.error", { error: robot.error })) : null,
  );
}

/** Who acknowledged an alert: a person's name, or a screen's number. */
function whoSaw(actor) {
  const who = String(actor);
  if (who.startsWith("user:")) return who.slice(5);
  if (who.startsWith("token:")) return t("alert.device", { id: who.slice(6) });
  return who;
}

export function alertHeadline(alert) {
  const subject = alert.subject ?? "";
  if (alert.kind === "call_waiting") {
    const at = String(subject).lastIndexOf("/");
    const table = at < 0 ? String(subject) : subject.slice(0, at);
    const what = at < 0 ? "" : subject.slice(at + 1);
    return t(CALLS[what] || "alert.kind.callWaiting.other", { table });
  }
  if (ALERT_KINDS[alert.kind]) return t(ALERT_KINDS[alert.kind], { subject });
  return alert.message || t("alert.kind.other", { subject });
}

export function alertItem(alert, now) {
  return el(
    "li",
    { class: alert.acked_by ? "alert seen" : "alert" },
    el("span", { class: "alert-what" }, alertHeadline(alert)),
    " ",
    el("span", { class: "muted" }, t("alert.since", { time: clock(alert.since, now) })),
    " ",
    el("span", { class: "alert-seen" }, alert.acked_by ? t("alert.seenBy", { who: whoSaw(alert.acked_by) }) : t("alert.notSeen")),
  );
}
