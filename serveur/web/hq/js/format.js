// Numbers, waits and times as a manager reads them, in the page's language: counts with the
// language's digits grouping (Intl.NumberFormat), waits in minutes or seconds as words, times
// as clock times on this device's clock (with the day when it is not today's).

import { locale } from "./i18n.js";

export const DASH = "–";

export function count(v) {
  if (v === null || v === undefined) return DASH;
  return new Intl.NumberFormat(locale(), { maximumFractionDigits: 0 }).format(v);
}

function unit(value, name) {
  return new Intl.NumberFormat(locale(), { style: "unit", unit: name, unitDisplay: "long" }).format(value);
}

/** A wait in words: "45 seconds" under a minute and a half, else whole minutes ("9 minutes"). */
export function wait(s) {
  if (s === null || s === undefined) return DASH;
  if (s < 90) return unit(Math.round(s), "second");
  return unit(Math.round(s / 60), "minute");
}

function sameDay(a, b) {
  return a.getFullYear() === b.getFullYear() && a.getMonth() === b.getMonth() && a.getDate() === b.getDate();
}

/** A moment (Unix seconds) as a clock time, "14:05"; with its day ("Tue 24 Nov, 14:05") when it
 *  is not on the same day as `now` (Unix seconds: the centre's clock). */
export function clock(ts, now = Date.now() / 1000) {
  if (ts === null || ts === undefined) return DASH;
  const when = new Date(ts * 1000);
  const opts = { hour: "numeric", minute: "2-digit" };
  if (!sameDay(when, new Date(now * 1000))) Object.assign(opts, { weekday: "short", day: "numeric", month: "short" });
  return new Intl.DateTimeFormat(locale(), opts).format(when);
}

/** A service day's label ("2026-11-24") as words: "Tue 24 Nov". */
export function dayWords(label) {
  const [y, m, d] = String(label).split("-").map(Number);
  if (!y || !m || !d) return String(label);
  return new Intl.DateTimeFormat(locale(), { timeZone: "UTC", weekday: "short", day: "numeric", month: "short" }).format(
    new Date(Date.UTC(y, m - 1, d)),
  );
}

/** This device's UTC offset now, as the centre's `utc_offset` reads it: "+08:00". */
export function utcOffset(date = new Date()) {
  const minutes = -date.getTimezoneOffset();
  const sign = minutes < 0 ? "-" : "+";
  const a = Math.abs(minutes);
  return `${sign}${String(Math.floor(a / 60)).padStart(2, "0")}:${String(a % 60).padStart(2, "0")}`;
}
