// The Statistics tab's charts, drawn as inline SVG (no library: the console works offline): a
// bar or line chart of one value per period, and the forecast's bar per fleet size. Each is an
// image with an aria-label summary given by its caller. Its own module so that the drawing is
// apart from the figures it draws.

import { t } from "../../i18n.js";
import { fmt, minutes } from "./format.js";

const SVG = "http://www.w3.org/2000/svg";

function svg(tag, attrs = {}, ...children) {
  const node = document.createElementNS(SVG, tag);
  for (const [k, v] of Object.entries(attrs)) if (v !== null && v !== undefined) node.setAttribute(k, String(v));
  for (const c of children) if (c) node.append(c instanceof Node ? c : document.createTextNode(String(c)));
  return node;
}

/** About how wide `text` is at 12 px (CJK characters are about twice as wide). */
function textWidth(text) {
  let w = 0;
  for (const ch of text) w += /[\u2e80-\uffef]/.test(ch) ? 12 : 7;
  return w;
}

/** A round top for an axis: 1, 2, 5 times a power of ten, at least `max`. */
function niceTop(max) {
  if (!(max > 0)) return 1;
  const p = 10 ** Math.floor(Math.log10(max));
  for (const m of [1, 2, 5, 10]) if (m * p >= max) return m * p;
  return 10 * p;
}

/**
 * A chart of one value per period: bars, or a line with a dot per period (null: no dot, the
 * line broken). `labels` name the periods; `tick` writes an axis value. Drawn to `width` px.
 */
export function chart({ kind, values, labels, tick, width, label }) {
  const height = 220;
  const top_ = niceTop(Math.max(0, ...values.filter((v) => v !== null)));
  // The middle line only where it is a round value (no "2.5 dishes").
  const ticks = kind === "bars" && !Number.isInteger(top_ / 2) ? [0, top_] : [0, top_ / 2, top_];
  const tickText = ticks.map((v) => tick(v));
  const left = 12 + Math.max(...tickText.map(textWidth)); // room for the longest
  const right = 10;
  const top = 18;
  const bottom = 34;
  const w = Math.max(200, width);
  const plotW = w - left - right;
  const plotH = height - top - bottom;
  const y = (v) => top + plotH - (v / top_) * plotH;
  const band = plotW / Math.max(1, values.length);
  const root = svg("svg", { class: `chart chart-${kind}`, viewBox: `0 0 ${w} ${height}`, width: w, height, role: "img", "aria-label": label });
  const grid = svg("g", { class: "chart-grid", "aria-hidden": "true" });
  ticks.forEach((v, i) => {
    grid.append(
      svg("line", { x1: left, x2: w - right, y1: y(v), y2: y(v) }),
      svg("text", { x: left - 6, y: y(v) + 4, "text-anchor": "end" }, tickText[i]),
    );
  });
  root.append(grid);
  // Period names under the plot, thinned so that they do not overlap.
  const room = Math.max(1, ...labels.map(textWidth)) + 12;
  const every = Math.max(1, Math.ceil(values.length / Math.max(1, Math.floor(plotW / room))));
  const axis = svg("g", { class: "chart-axis", "aria-hidden": "true" });
  labels.forEach((text, i) => {
    if (i % every) return;
    // Centred under its period, kept inside the picture at either end.
    let x = left + band * (i + 0.5);
    let anchor = "middle";
    const half = textWidth(text) / 2;
    if (x - half < 2) [x, anchor] = [2, "start"];
    else if (x + half > w - 2) [x, anchor] = [w - 2, "end"];
    axis.append(svg("text", { x, y: height - bottom + 18, "text-anchor": anchor }, text));
  });
  root.append(axis);
  const marks = svg("g", { class: "chart-marks" });
  if (kind === "bars") {
    const bw = Math.max(2, Math.min(48, band * 0.7));
    const numbers = svg("g", { class: "chart-values", "aria-hidden": "true" });
    values.forEach((v, i) => {
      const h = v ? plotH - (y(v) - top) : 0;
      if (band >= 24 && v) numbers.append(svg("text", { x: left + band * (i + 0.5), y: top + plotH - h - 4, "text-anchor": "middle" }, tick(v)));
      marks.append(
        svg(
          "rect",
          { class: "bar", x: left + band * (i + 0.5) - bw / 2, y: top + plotH - h, width: bw, height: Math.max(h, 0), "data-value": v },
          svg("title", {}, `${labels[i]}: ${tick(v ?? 0)}`),
        ),
      );
    });
    root.append(numbers);
  } else {
    let path = "";
    values.forEach((v, i) => {
      if (v === null) return;
      const x = left + band * (i + 0.5);
      const start = i === 0 || values[i - 1] === null;
      path += `${start ? "M" : "L"}${x.toFixed(1)},${y(v).toFixed(1)} `;
    });
    if (path) marks.append(svg("path", { class: "line", d: path.trim() }));
    values.forEach((v, i) => {
      if (v === null) return;
      marks.append(svg("circle", { class: "dot", cx: left + band * (i + 0.5), cy: y(v), r: 4 }, svg("title", {}, `${labels[i]}: ${tick(v)}`)));
    });
  }
  root.append(marks);
  return root;
}

/**
 * "How many robots?": one bar per fleet size tried, as tall as the wait within which 95 % of
 * the replayed day's dishes reached the table (minutes); the fleet the site has now marked.
 * A fleet still replaying (or failed) keeps its place, with no bar.
 */
export function fleetChart({ fleets, current, width, label }) {
  const height = 200;
  const values = fleets.map((f) => (f.state === "done" && f.wait_p95 !== null && f.wait_p95 !== undefined ? f.wait_p95 / 60 : null));
  const top_ = niceTop(Math.max(0, ...values.filter((v) => v !== null)));
  const ticks = [0, top_ / 2, top_];
  const tickText = ticks.map((v) => fmt(v, { maximumFractionDigits: 1 }));
  const left = 12 + Math.max(...tickText.map(textWidth));
  const right = 10;
  const top = 20;
  const bottom = 44; // the fleet size, and "now" under the current one
  const w = Math.max(200, width);
  const plotW = w - left - right;
  const plotH = height - top - bottom;
  const y = (v) => top + plotH - (v / top_) * plotH;
  const band = plotW / Math.max(1, fleets.length);
  const bw = Math.max(8, Math.min(56, band * 0.6));
  const root = svg("svg", { class: "chart chart-fleets", viewBox: `0 0 ${w} ${height}`, width: w, height, role: "img", "aria-label": label });
  const grid = svg("g", { class: "chart-grid", "aria-hidden": "true" });
  ticks.forEach((v, i) => {
    grid.append(svg("line", { x1: left, x2: w - right, y1: y(v), y2: y(v) }), svg("text", { x: left - 6, y: y(v) + 4, "text-anchor": "end" }, tickText[i]));
  });
  root.append(grid);
  const axis = svg("g", { class: "chart-axis", "aria-hidden": "true" });
  const numbers = svg("g", { class: "chart-values", "aria-hidden": "true" });
  const marks = svg("g", { class: "chart-marks" });
  fleets.forEach((f, i) => {
    const x = left + band * (i + 0.5);
    const now = f.robots === current;
    const name = t("stats.fc.fleet", { count: f.robots });
    axis.append(svg("text", { x, y: height - bottom + 18, "text-anchor": "middle", class: now ? "now" : null }, textWidth(name) + 4 <= band ? name : fmt(f.robots)));
    if (now) axis.append(svg("text", { x, y: height - bottom + 34, "text-anchor": "middle", class: "now" }, t("stats.fc.now")));
    const v = values[i];
    if (v === null) return;
    const h = plotH - (y(v) - top);
    numbers.append(svg("text", { x, y: top + plotH - h - 4, "text-anchor": "middle" }, fmt(v, { maximumFractionDigits: 1, minimumFractionDigits: 1 })));
    marks.append(
      svg(
        "rect",
        { class: now ? "bar now" : "bar", x: x - bw / 2, y: top + plotH - h, width: bw, height: Math.max(h, 0), "data-robots": f.robots, "data-value": f.wait_p95 },
        svg("title", {}, `${name}: ${minutes(f.wait_p95)}`),
      ),
    );
  });
  root.append(axis, numbers, marks);
  return root;
}

