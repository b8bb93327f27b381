// The Statistics tab's numbers, dates and times as people read them, in the page's language:
// counts, minutes, distances, a trip's clock time and a period's name, on the restaurant's clock
// as this device knows it (its UTC offset). Shared by the panel, its tables, charts, trip
// history, CSV files and forecast, so that each writes a figure the same way.

import { lang, t } from "../../i18n.js";

const DAY_START = 4; // a service day runs from 04:00 to 04:00 (serveur stats --day-start)
const HTML_LANG = { en: "en", zh: "zh-Hans", ms: "ms" };

export function locale() {
  return HTML_LANG[lang()] || "en";
}

export function fmt(value, options = {}) {
  return new Intl.NumberFormat(locale(), options).format(value);
}

export const DASH = "–";

export function count(v) {
  return v === null || v === undefined ? DASH : fmt(v, { maximumFractionDigits: 0 });
}

export function one(v) {
  return v === null || v === undefined ? DASH : fmt(v, { maximumFractionDigits: 1, minimumFractionDigits: 1 });
}

/** Seconds as minutes: "7.3 min". */
export function minutes(s) {
  if (s === null || s === undefined) return DASH;
  return fmt(s / 60, { style: "unit", unit: "minute", unitDisplay: "short", maximumFractionDigits: 1 });
}

/** A short time span as people say it: "45 s" under a minute and a half, else "7.3 min". */
export function duration(s) {
  if (s === null || s === undefined) return DASH;
  if (s < 90) return fmt(Math.round(s), { style: "unit", unit: "second", unitDisplay: "short" });
  return minutes(s);
}

/** Seconds as hours and minutes for long spans (busy time): "2 h 05 min". */
export function span(s) {
  if (s === null || s === undefined) return DASH;
  const m = Math.round(s / 60);
  if (m < 60) return minutes(s);
  return t("stats.hoursMinutes", { h: fmt(Math.floor(m / 60)), m: String(m % 60).padStart(2, "0") });
}

export function percent(v) {
  return v === null || v === undefined ? DASH : fmt(v, { style: "percent", maximumFractionDigits: 0 });
}

export function distance(m) {
  if (m === null || m === undefined) return DASH;
  if (m >= 1000) return fmt(m / 1000, { style: "unit", unit: "kilometer", unitDisplay: "short", maximumFractionDigits: 1 });
  return fmt(m, { style: "unit", unit: "meter", unitDisplay: "short", maximumFractionDigits: 0 });
}

/** This device's UTC offset (minutes) at a local date ("2026-11-24"), and as "+08:00". */
export function offsetAt(date) {
  const [y, mo, d] = date.split("-").map(Number);
  return -new Date(y, mo - 1, d, 12).getTimezoneOffset();
}

export function offsetText(minutes_) {
  const sign = minutes_ < 0 ? "-" : "+";
  const a = Math.abs(minutes_);
  return `${sign}${String(Math.floor(a / 60)).padStart(2, "0")}:${String(a % 60).padStart(2, "0")}`;
}

/** A Date whose UTC fields are the restaurant's clock at epoch `ts` (microseconds kept, as
 *  Python's datetime.fromtimestamp does). */
function wall(ts, offset) {
  const us = Math.round((ts + offset * 60) * 1e6);
  return new Date(Math.floor(us / 1000));
}

const pad = (n, w = 2) => String(n).padStart(w, "0");

/** "2026-11-24 19:32:05", as the command's CSV writes a time ("" for none). */
export function csvTime(ts, offset) {
  if (ts === null || ts === undefined) return "";
  const d = wall(ts, offset);
  return `${d.getUTCFullYear()}-${pad(d.getUTCMonth() + 1)}-${pad(d.getUTCDate())} ${pad(d.getUTCHours())}:${pad(d.getUTCMinutes())}:${pad(d.getUTCSeconds())}`;
}

export function clock(ts, offset) {
  if (ts === null || ts === undefined) return DASH;
  return new Intl.DateTimeFormat(locale(), { timeZone: "UTC", hour: "2-digit", minute: "2-digit" }).format(wall(ts, offset));
}

export function dayName(ts, offset) {
  return new Intl.DateTimeFormat(locale(), { timeZone: "UTC", weekday: "short", day: "numeric", month: "short" }).format(wall(ts, offset));
}

/** A date field "2026-11-24" as words: "Tue 24 Nov". */
export function dateWords(date) {
  const [y, m, d] = date.split("-").map(Number);
  return new Intl.DateTimeFormat(locale(), { timeZone: "UTC", weekday: "short", day: "numeric", month: "short" }).format(new Date(Date.UTC(y, m - 1, d)));
}

/** A period's label ("2026-11-24" or "2026-11-24 19:00") as a reader says it. */
export function periodWords(label, several) {
  const [date, hour] = label.split(" ");
  if (!hour) return dateWords(date);
  return several ? `${dateWords(date)} ${hour}` : hour;
}

export function isoDate(d) {
  return `${d.getFullYear()}-${pad(d.getMonth() + 1)}-${pad(d.getDate())}`;
}

/** Today's service day on this device (before 04:00 it is still yesterday's). */
export function serviceToday() {
  return new Date(Date.now() - DAY_START * 3600 * 1000);
}

export function addDays(d, n) {
  const out = new Date(d);
  out.setDate(out.getDate() + n);
  return out;
}
