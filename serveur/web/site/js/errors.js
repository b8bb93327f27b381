// Every error the server can answer, as one sentence for the person holding the phone, in the
// page's language, built from the error's `details` (and the request it answers) — never the
// server's English message, a status code, coordinates or ROS words (docs/protocol.md,
// "Errors": the codes are stable, so the words are chosen here, per code).
//
// A code is worded by one function of the table below; each picks the most precise sentence
// its details allow and falls back to the code's general one. The server's own message stays
// available to an integrator in the browser's console (ui.js logs it), not on the screen.

import { statusName, t } from "./i18n.js";

/** A dish's status in the words of the dish lists ("Cooking", "At the pass"...). */
export function dishState(status) {
  const key = DISH_STATES[status];
  return key ? t(key) : t("dishState.other");
}

const DISH_STATES = {
  ordered: "dishState.ordered",
  cooking: "dishState.cooking",
  pending: "dishState.pending",
  assigned: "dishState.assigned",
  delivered: "dishState.delivered",
  voided: "dishState.voided",
  returned: "dishState.returned",
};

const UNREACHABLE = {
  outside_map: "errors.unreachable.outside",
  unknown: "errors.unreachable.unknown",
  occupied: "errors.unreachable.occupied",
};

const BACKUP = {
  not_a_backup: "errors.backup.notABackup",
  newer: "errors.backup.newer",
  damaged: "errors.backup.damaged",
  not_found: "errors.backup.notFound",
  busy: "errors.backup.busy",
  disk: "errors.backup.disk",
  off: "errors.backup.off",
};

/** The first of `keys` present (and not empty) in `obj`, as [key, value], or null. */
function first(obj, keys) {
  for (const k of keys) if (obj && obj[k] !== undefined && obj[k] !== null && obj[k] !== "") return [k, obj[k]];
  return null;
}

function notFound(d, req) {
  if (Array.isArray(d.dishes) && d.dishes.length) return t("errors.notFound.dishes", { dishes: d.dishes.join(", ") });
  const hit = first(d, ["robot", "waypoint", "table", "zone", "user", "order", "task", "alert", "token", "call", "button", "ticket"]);
  if (!hit) return t("errors.notFound");
  const [what, name] = hit;
  if (what === "robot") return t("errors.notFound.robot", { name });
  if (what === "waypoint" || what === "table") return t("errors.notFound.place", { name });
  if (what === "zone") return t("errors.notFound.zone", { name });
  if (what === "user") return t("errors.notFound.user", { name });
  if (what === "order") return t("errors.notFound.order");
  if (what === "task") return t("errors.notFound.trip");
  if (what === "alert") return t("errors.notFound.alert");
  if (what === "call") return t("errors.notFound.call");
  if (what === "button") return t("errors.notFound.button", { name });
  if (what === "ticket") return t("errors.notFound.ticket");
  return req && req.clientmsg === "account" ? t("errors.notFound.token") : t("errors.notFound");
}

function stale(d, req) {
  if (d.order !== undefined && d.order !== null) return t("errors.stale.dish", { status: dishState(d.status) });
  const robot = d.robot || (req && req.robot) || "";
  return t("errors.stale.robot", { name: robot, status: statusName(d.status) });
}

function notAllowed(d, req) {
  const robot = (req && req.robot) || "";
  return robot
    ? t("errors.notAllowed.robot", { name: robot, status: statusName(d.status) })
    : t("errors.notAllowed", { status: statusName(d.status) });
}

function unreachable(d) {
  if (d.table) return t("errors.unreachable.blocked", { table: d.table });
  return t(UNREACHABLE[d.reason] || "errors.unreachable");
}

// Why a guest's call cannot be closed: it already was (details.state).
const CALL_CLOSED = { answered: "errors.conflict.callAnswered", cancelled: "errors.conflict.callCancelled" };

function conflict(d, req) {
  if (d.reason === "no_dish_return") return t("errors.conflict.noDishReturn");
  if (d.reason === "no_dock") return t("errors.conflict.noDock", { name: d.robot || (req && req.robot) || "" });
  if (d.call !== undefined) return t(CALL_CLOSED[d.state] || "errors.conflict.callClosed");
  if (d.ticket !== undefined) return t("errors.conflict.ticket");
  if (d.button) return t("errors.conflict.buttonTaken", { name: d.button });
  if (d.acked_by) return t("errors.conflict.seen", { who: d.acked_by });
  if (d.forecast !== undefined) return t("errors.conflict.forecast");
  if (d.order !== undefined && d.status) return t("errors.conflict.dish", { status: dishState(d.status) });
  if (d.robot && d.reason === "lost") return t("errors.conflict.lost", { name: d.robot });
  if (d.robot && (d.trip !== undefined || d.task !== undefined)) return t("errors.conflict.onTrip", { name: d.robot });
  if (d.robot) return t("errors.conflict.robotTaken", { name: d.robot });
  if (d.waypoint && (d.homes || d.orders || d.trips || d.tokens || d.blocked)) {
    return t("errors.conflict.placeInUse", { name: d.waypoint });
  }
  if (d.waypoint) return t("errors.conflict.placeTaken", { name: d.waypoint });
  if (d.zone) return t("errors.conflict.zoneTaken", { name: d.zone });
  if (d.user) return t("errors.conflict.user", { name: d.user });
  if (d.orders !== undefined) return t("errors.conflict.dishes");
  if (req && req.clientmsg === "control") return t("errors.conflict.noHome", { name: req.robot || "" });
  return t("errors.conflict");
}

// The till's settings and the owner's ticket pattern (the `till` verb): what was not right.
const TILL_FIELDS = {
  port: "errors.invalid.tillPort",
  printer: "errors.invalid.tillPrinter",
  marks: "errors.invalid.tillMarks",
  pattern: "errors.invalid.tillPattern",
  csv: "errors.invalid.tillMenu",
};

function forbidden(d) {
  if (d.table) return t("errors.forbidden.table", { table: d.table });
  return t("errors.forbidden");
}

function rateLimited(d) {
  return t("errors.rateLimited", { s: Math.max(1, Math.ceil(Number(d.retry_after) || 1)) });
}

function invalid(d) {
  if (d.field === "language") return t("errors.invalid.language");
  if (d.field === "trays") return d.trays ? t("errors.invalid.trays", { trays: d.trays }) : t("errors.invalid.traysAny");
  if (d.field === "table" && d.table) return t("errors.invalid.notTable", { name: d.table });
  const types = Array.isArray(d.errors) ? d.errors.map((e) => e && e.type) : [];
  if (types.includes("charge_levels")) return t("errors.invalid.chargeLevels");
  if (d.field === "start" || d.field === "end") return t("errors.invalid.dates");
  if (Object.hasOwn(TILL_FIELDS, d.field)) return t(TILL_FIELDS[d.field]);
  return t("errors.invalid");
}

/** code -> (details, request) -> sentence. Every code of docs/protocol.md's error table. */
const WORDING = {
  unauthorized: () => t("errors.unauthorized"),
  forbidden,
  rate_limited: rateLimited,
  bad_json: () => t("errors.badJson"),
  unknown_message: () => t("errors.unknownMessage"),
  invalid_field: invalid,
  not_found: notFound,
  not_allowed_in_status: notAllowed,
  conflict,
  store_error: () => t("errors.store"),
  map_error: () => t("errors.map"),
  navigation_error: () => t("errors.navigation"),
  unreachable,
  stale,
  rosbridge_error: () => t("errors.rosbridge"),
  link_error: (d, req) => (req && req.robot ? t("errors.link.robot", { name: req.robot }) : t("errors.link")),
  backup_error: (d) => t(BACKUP[d.reason] || "errors.backup"),
  internal_error: () => t("errors.internal"),
};

/** The codes this page can word (a test walks docs/protocol.md's table against it). */
export const WORDED_CODES = Object.freeze(Object.keys(WORDING));

/**
 * The sentence for a server's error `code` with its `details`, answering `request` (the message
 * sent, when known); null for a code this version does not know (a newer server's).
 */
export function wordError(code, details, request) {
  const word = WORDING[code];
  return word ? word(details || {}, request || null) : null;
}
