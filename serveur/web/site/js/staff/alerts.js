// Alerts on every tab (the `alerts` topic): a badge in the header with the number nobody has
// acknowledged yet, a banner listing the active ones with an Acknowledge button each ("seen by
// Ana at 19:42" once someone has), and a chime for each new critical alert, made with WebAudio
// (no audio file), that can be muted on this device (ring.js). A cleared alert leaves the
// banner. A guest's call nobody answered (`call_waiting`, subject "T3/waiter") reads as what
// the table asked for (callwords.js).

import { act, el, formatTime, KeyedList } from "../ui.js";
import { onLangChange, t } from "../i18n.js";
import { blockWords, troubleWords } from "./trouble.js";
import { consoleSound } from "./ring.js";
import { callAlertWords } from "./callwords.js";

// The headline of each kind, from its subject (a robot or a table), in the page's language; the
// detail is the cause as the live records tell it (the robot's error, why the table is blocked,
// the zones a robot waits for and who is in them).
const KINDS = {
  robot_error: "alerts.kind.robotError",
  robot_offline: "alerts.kind.robotOffline",
  low_battery: "alerts.kind.lowBattery",
  waiting_at_table: "alerts.kind.waitingAtTable",
  dish_waiting: "alerts.kind.dishWaiting",
  table_unreachable: "alerts.kind.tableUnreachable",
  zone_wait: "alerts.kind.zoneWait",
  robot_lost: "alerts.kind.robotLost",
  not_charging: "alerts.kind.notCharging",
  ticket_unread: "alerts.kind.ticketUnread",
  printer_down: "alerts.kind.printerDown",
};

/** Who acknowledged: a person's name, or the device token's number. */
function whoSaw(actor) {
  if (!actor) return "?";
  if (actor.startsWith("user:")) return actor.slice(5);
  if (actor.startsWith("token:")) return t("alerts.device", { id: actor.slice(6) });
  return actor;
}

export class AlertsPanel {
  constructor({ banner, badge, mute }, conn, live) {
    this.banner = banner;
    this.badge = badge;
    this.mute = mute;
    this.conn = conn;
    this.live = live;
    // Two short falling tones (sound.js, as the robot and table screens ring), under the
    // console's one sound choice (ring.js: a guest's call rings under it too).
    this.chime = consoleSound.chime([880, 660]);
    this.chimes = 0; // how many were sounded (banner's data-chimes: what a test can read)
    this.heard = new Set(); // alert ids already seen by this page: a chime once per alert
    this.list = el("ul", { class: "alert-list" });
    this.rows = new KeyedList(this.list, {
      key: (alert) => alert.id,
      signature: (alert) => [alert.severity, alert.message, alert.acked_at, alert.acked_by, this._detail(alert)],
      build: (alert) => this._row(alert),
    });
    this.banner.append(this.list);
    this.mute.addEventListener("click", () => consoleSound.setMuted(!consoleSound.muted));
    consoleSound.onChange(() => this._showMute());
    live.addEventListener("change", (e) => {
      if (["alerts", "robots", "blocks", "leases"].includes(e.detail.topic)) this.render();
    });
    onLangChange(() => {
      this.rows.invalidate();
      this._showMute();
      this.render();
    });
    this._showMute();
    this.render();
  }

  _showMute() {
    // The words say the state ("Sound off"); the hint says what a press does.
    const muted = consoleSound.muted;
    this.mute.dataset.muted = String(muted);
    this.mute.textContent = muted ? t("alerts.soundOff") : t("alerts.soundOn");
    this.mute.title = muted ? t("alerts.unmuteHint") : t("alerts.muteHint");
  }

  render() {
    const alerts = [...this.live.alerts.values()].sort(
      (a, b) => (a.severity === b.severity ? 0 : a.severity === "critical" ? -1 : 1) || a.id - b.id,
    );
    let fresh = false;
    for (const alert of alerts) {
      if (!this.heard.has(alert.id)) {
        this.heard.add(alert.id);
        if (alert.severity === "critical" && !alert.acked_at) fresh = true;
      }
    }
    this.rows.update(alerts);
    if (fresh && !consoleSound.muted) {
      this.chime.play();
      this.chimes += 1;
      this.banner.dataset.chimes = String(this.chimes);
    }
    const unseen = alerts.filter((a) => !a.acked_at).length;
    this.banner.hidden = !alerts.length;
    this.badge.hidden = !unseen;
    this.badge.textContent = String(unseen);
    this.badge.setAttribute("aria-label", t("alerts.badge", { count: unseen }));
    this.badge.title = t("alerts.badge", { count: unseen });
  }

  /**
   * The cause, from the live records: the robot's last error, its battery, the block's reason,
   * the zones a robot waits for ("Waiting for aisle (held by r2)").
   */
  _detail(alert) {
    if (alert.kind === "call_waiting") return t("alerts.callWaitingWhat");
    if (alert.kind === "ticket_unread") return t("alerts.ticketUnreadWhat");
    if (alert.kind === "printer_down") return t("alerts.printerDownWhat");
    if (alert.kind === "table_unreachable") {
      const block = this.live.blocks.get(alert.subject);
      return block ? blockWords(block) : null;
    }
    const robot = this.live.robots.get(alert.subject);
    if (!robot) return null;
    if (alert.kind === "robot_error") return troubleWords(robot, this.live);
    if (alert.kind === "low_battery" && typeof robot.battery === "number") {
      return t("robots.battery", { value: t("robots.batteryPercent", { percent: Math.round(robot.battery * 100) }) });
    }
    if (alert.kind === "waiting_at_table") return this.live.destination(alert.subject);
    if (alert.kind === "zone_wait") return this._zoneWait(robot);
    if (alert.kind === "robot_lost") return t("robots.lost");
    if (alert.kind === "not_charging") return t("alerts.notChargingWhat");
    return null;
  }

  /** The zones `robot` waits for (its live `waiting_for`) and the robots holding them, or null. */
  _zoneWait(robot) {
    const zones = robot.waiting_for;
    if (!Array.isArray(zones) || !zones.length) return null;
    const holders = new Set();
    for (const zone of zones) {
      for (const r of this.live.leases.get(zone)?.holders || []) if (r !== robot.name) holders.add(r);
    }
    const names = zones.join(", ");
    return holders.size
      ? t("robots.waitingHeld", { zones: names, robots: [...holders].sort().join(", ") })
      : t("alerts.zoneWaitFor", { zones: names });
  }

  _row(alert) {
    const kind = `alert alert-${alert.severity === "critical" ? "critical" : "warning"}`;
    return el("li", { "data-alert": alert.id, class: alert.acked_at ? `${kind} acked` : kind }, ...this._content(alert));
  }

  _content(alert) {
    const detail = this._detail(alert);
    const headline =
      alert.kind === "call_waiting"
        ? callAlertWords(alert.subject)
        : t(KINDS[alert.kind] || "alerts.kind.other", { subject: alert.subject });
    const since = t("alerts.since", { time: formatTime(alert.raised_at) });
    const parts = [
      el("span", { class: "alert-severity" }, alert.severity === "critical" ? t("alerts.critical") : t("alerts.warning")),
      el("strong", { class: "alert-text" }, headline),
      detail ? el("span", { class: "alert-detail" }, detail) : null,
      el("span", { class: "alert-since muted" }, since),
    ];
    if (alert.acked_at) {
      parts.push(
        el("span", { class: "alert-seen" }, t("alerts.seenBy", { who: whoSaw(alert.acked_by), time: formatTime(alert.acked_at) })),
      );
    } else {
      parts.push(
        el("button", {
          class: "ack",
          "data-needs-online": true,
          "aria-label": t("alerts.ackFor", { what: headline }),
          text: t("alerts.ack"),
          onclick: (e) => act(e.currentTarget, () => this.conn.request({ clientmsg: "ack", alert: alert.id })),
        }),
      );
    }
    return parts.filter(Boolean);
  }
}
