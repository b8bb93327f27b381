// The pass's list of trips queued or under way (issue.js's cart card): a delivery with its status,
// its robot and its tables with how many dishes each ("trip 4 (under way, r1) · T3 (2) → T5
// (1)"); a robot sent for plates or cruising in those words (trips.js).

import { el, KeyedList } from "../ui.js";
import { t } from "../i18n.js";
import { otherTripWords } from "./trips.js";

function taskStatus(status) {
  return status === "queued" ? t("task.queued") : status === "active" ? t("task.active") : status;
}

export class TripList {
  constructor(live) {
    this.live = live;
    this.list = el("ul", { class: "trips", "data-i18n-aria-label": "issue.trips" });
    this.rows = new KeyedList(this.list, {
      key: (trip) => trip.id,
      signature: (trip) => [trip.kind, trip.status, trip.robot, trip.stops.map((s) => [s.table, s.orders.length])],
      build: (trip) => this._row(trip),
      empty: () => el("li", { class: "muted" }, t("issue.noTrips")),
    });
  }

  render() {
    this.rows.update([...this.live.tasks.values()].filter((trip) => trip.status === "queued" || trip.status === "active"));
  }

  _row(trip) {
    const other = otherTripWords(trip); // a robot for plates, a cruise
    if (other) return el("li", {}, trip.robot ? t("issue.otherTripRobot", { trip: other, robot: trip.robot }) : other);
    const status = taskStatus(trip.status);
    return el(
      "li",
      {},
      (trip.robot ? t("issue.tripRobot", { id: trip.id, status, robot: trip.robot }) : t("issue.trip", { id: trip.id, status })) + " · ",
      trip.stops.map((s) => `${s.table} (${s.orders.length})`).join(" → "),
    );
  }
}
