// A robot's trip in a waiter's words, by the trip's kind and the purpose of the stop it is at or
// going to (docs/protocol.md, "Trips of other kinds"): a delivery ("trip 3: T3, T5 (now T5)",
// "Birthday at T4" at a stop with a special dish), a bussing trip ("Going for plates at T3",
// "Taking plates from T3", "At the dish return"), a cruise ("Cruising: pass → T1 → T5"). A robot
// on any trip is Delivering between stops and Delivered at one: the status word is chosen here
// too, so a bussing stop never reads "At the table" or "Delivered". Pure words: no DOM.

import { statusName, t } from "../i18n.js";

/** The robot's trip and the stop it is at or going to: {task, stop} (either may be null). */
export function tripOf(live, robot) {
  const task = robot && robot.current_task != null ? live.tasks.get(robot.current_task) || null : null;
  const stop = task ? task.stops[task.current_stop] || null : null;
  return { task, stop };
}

/** "delivery", "bussing" or "cruise" (a record from before the kinds: a delivery). */
export function tripKind(task) {
  return (task && task.kind) || "delivery";
}

/** Whether the robot goes round a cruise now. */
export function cruising(live, robot) {
  return tripKind(tripOf(live, robot).task) === "cruise";
}

/** A stop whose dishes include a special one (a birthday): its message, or null. */
export function specialAt(live, stop) {
  if (!stop || (stop.purpose && stop.purpose !== "deliver")) return null;
  for (const id of stop.orders || []) {
    const order = live.orders.get(id);
    if (order && order.special) return order.special;
  }
  return null;
}

/** The status badge's word: the status, or what the robot does on its trip's stop. */
export function statusWords(live, robot) {
  const { task, stop } = tripOf(live, robot);
  const kind = tripKind(task);
  if (stop && robot.status === "Delivered") {
    if (stop.purpose === "collect") return t("trips.status.collecting");
    if (stop.purpose === "unload") return t("trips.status.unloading");
    if (stop.purpose === "visit") return t("trips.status.visiting");
    if (specialAt(live, stop)) return t("trips.status.birthday");
  }
  if (stop && robot.status === "Delivering") {
    if (kind === "bussing") return t(stop.purpose === "unload" ? "trips.status.returning" : "trips.status.goingForPlates");
    if (kind === "cruise") return t("trips.status.cruising");
  }
  if (robot.status === "Transit" && robot.to_dock) return t("trips.status.toCharge");
  return statusName(robot.status);
}

/** The robot row's trip line. */
export function tripWords(live, robot) {
  if (robot.current_task == null) {
    if (robot.status === "Charging") return robot.dock ? t("trips.onDock", { dock: robot.dock }) : t("trips.onDockAny");
    return t("robots.noTrip");
  }
  const { task, stop } = tripOf(live, robot);
  if (!task) return t("robots.tripId", { id: robot.current_task });
  const at = robot.status === "Delivered";
  const kind = tripKind(task);
  if (kind === "cruise") {
    const route = task.stops.map((s) => s.table).join(" → ");
    return stop && at ? t("trips.cruiseAt", { place: stop.table, route }) : t("trips.cruise", { route });
  }
  if (kind === "bussing") {
    const tables = task.stops.filter((s) => s.purpose !== "unload").map((s) => s.table).join(", ");
    if (!stop) return t("trips.bussing", { tables });
    if (stop.purpose === "unload") return t(at ? "trips.atDishReturn" : "trips.toDishReturn", { place: stop.table });
    return t(at ? "trips.platesFrom" : "trips.platesGoing", { table: stop.table });
  }
  const tables = task.stops.map((s) => s.table).join(", ");
  const words = stop ? t("robots.tripNow", { id: task.id, tables, now: stop.table }) : t("robots.trip", { id: task.id, tables });
  return specialAt(live, stop) ? t("trips.birthday", { table: stop.table, trip: words }) : words;
}

/** The catalog key of the robot's `next` button: what Done means at this stop. */
export function nextKey(live, robot) {
  const { stop } = tripOf(live, robot);
  if (!stop) return "robots.collected";
  if (stop.purpose === "collect") return "trips.next.collected";
  if (stop.purpose === "unload") return "trips.next.emptied";
  if (stop.purpose === "visit") return "trips.next.visit";
  return specialAt(live, stop) ? "trips.next.done" : "robots.collected";
}

/** A trip in the pass's list of trips: "Plates: T3, T5 → dish return", "Cruise: ..."; null for
 *  a delivery (the list words those itself). */
export function otherTripWords(task) {
  const kind = tripKind(task);
  const places = task.stops.map((s) => s.table).join(" → ");
  if (kind === "bussing") return t("trips.listBussing", { id: task.id, places });
  if (kind === "cruise") return t("trips.listCruise", { id: task.id, places });
  return null;
}
