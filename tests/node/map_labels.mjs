// The map's label placer (serveur/web/site/js/map/labels.js) on plain values, under Node: run by
// tests/web/test_map_labels.py (`node map_labels.mjs`, exit status 0 and "ok" when every check
// holds). `node map_labels.mjs bench` prints what one placement of a crowded room costs.
//
// The module is loaded from its source as a data: URL, so that it runs here as the ES module the
// browser loads (the site has no package.json to say so, and older Node would read it as
// CommonJS); it imports nothing.

import assert from "node:assert/strict";
import { readFileSync } from "node:fs";

const SOURCE = new URL("../../serveur/web/site/js/map/labels.js", import.meta.url);
const { placeLabels, overlap, segmentHitsBox, RINGS } = await import(
  "data:text/javascript;base64," + Buffer.from(readFileSync(SOURCE)).toString("base64")
);

// Text widths as a canvas measures system-ui roughly: 0.62 em a character (bold a little more).
function measure(font, text) {
  const size = Number(/(\d+)px/.exec(font)[1]);
  return text.length * size * (font.includes("bold") ? 0.66 : 0.62);
}

const table = (name, x, y) => ({ key: `place:${name}`, kind: "table", of: name, text: name, x, y, r: 8, size: 12, bold: true, prio: 0, keep: true });
const robot = (name, x, y, text = name) => ({ key: `robot:${name}`, kind: "robot", of: name, text, x, y, r: 9, size: 12, bold: true, pad: 4, prio: 2, keep: true });
const home = (name, x, y) => ({ key: `place:${name}`, kind: "home", of: name, text: name, x, y, r: 8, size: 12, prio: 3 });
const marker = (l) => ({ x: l.x, y: l.y, r: 7 });
const body = (l) => ({ x: l.x, y: l.y, r: 9 });

function circleHitsBox(c, b) {
  const dx = c.x - Math.max(b.x0, Math.min(c.x, b.x1));
  const dy = c.y - Math.max(b.y0, Math.min(c.y, b.y1));
  return dx * dx + dy * dy < c.r * c.r;
}

/** Every rule a placement must keep, whatever the labels. */
function checkPlacement(found, scene, what) {
  const { placed } = found;
  for (const [i, a] of placed.entries()) {
    assert.ok(a.x0 >= 0 && a.y0 >= 0 && a.x1 <= scene.width && a.y1 <= scene.height, `${what}: ${a.text} leaves the map`);
    for (const b of placed.slice(i + 1)) assert.ok(!overlap(a, b), `${what}: ${a.text} covers ${b.text}`);
    for (const c of scene.circles) assert.ok(!circleHitsBox(c, a), `${what}: ${a.text} covers a mark at ${c.x},${c.y}`);
    for (const r of scene.rects || []) assert.ok(!overlap(a, r), `${what}: ${a.text} is under a control`);
    for (const b of placed) {
      if (b !== a && b.leader) assert.ok(!segmentHitsBox(b.leader, a), `${what}: ${a.text} covers ${b.text}'s line`);
    }
    // Attached: next to its anchor, or on a line starting on the anchor's edge and ending on it.
    const nx = Math.max(a.x0, Math.min(a.ax, a.x1));
    const ny = Math.max(a.y0, Math.min(a.ay, a.y1));
    const gap = Math.hypot(nx - a.ax, ny - a.ay) - a.ar;
    if (a.leader) {
      const [sx, sy, ex, ey] = a.leader;
      assert.ok(Math.abs(Math.hypot(sx - a.ax, sy - a.ay) - a.ar) < 0.01, `${what}: ${a.text}'s line starts off its mark`);
      assert.ok(Math.abs(ex - nx) < 0.01 && Math.abs(ey - ny) < 0.01, `${what}: ${a.text}'s line ends off it`);
      assert.ok(gap <= RINGS[RINGS.length - 1] + 0.01, `${what}: ${a.text} is ${gap} px away`);
    } else {
      assert.ok(gap <= RINGS[0] + 0.01, `${what}: ${a.text} is ${gap} px away with no line`);
    }
  }
}

/** A crowded dining room on a phone's map (20 px a metre): 30 tables in rows of six 0.6 m apart
 *  (12 px), an aisle of 2.4 m between rows, robots parked on some, r1 headed to T5 beside T1,
 *  r6 to T30; six homes and the pass along the top; the legend's summary over a corner. */
function crowdedRoom(scale = 20) {
  const labels = [];
  const m = scale / 20; // px a metre / 20
  let n = 0;
  for (const [bx, by, rows] of [[30, 90, 3], [200, 110, 2]]) {
    for (let row = 0; row < rows; row++) {
      for (let i = 0; i < 6; i++) labels.push(table(`T${++n}`, (bx + i * 12) * m, (by + row * 60) * m));
    }
  }
  const at = (t, dx = 0, dy = 0) => [labels[t - 1].x + dx * m, labels[t - 1].y + dy * m];
  const robots = [
    robot("r1", ...at(1, 4, 7), "r1 → T5"),
    robot("r2", ...at(3)),
    robot("r3", ...at(8)),
    robot("r4", ...at(16)),
    robot("r5", ...at(21)),
    robot("r6", ...at(26, 0, -10), "r6 → T30"),
  ];
  labels.push(...robots);
  for (let i = 0; i < 6; i++) labels.push(home(`home${i + 1}`, (40 + i * 20) * m, 30 * m));
  labels.push({ ...home("pass", 180 * m, 30 * m), kind: "pass" });
  const circles = [...labels.filter((l) => l.kind !== "robot").map(marker), ...robots.map(body)];
  return { labels, scene: { circles, rects: [{ x0: 0, y0: 300 * m, x1: 100 * m, y1: 344 * m }], width: 358 * m, height: 344 * m } };
}

function tests() {
  // Free space: right of its mark, no line.
  {
    const scene = { circles: [], width: 200, height: 200 };
    const { placed } = placeLabels([table("T1", 100, 100)], scene, measure);
    assert.equal(placed.length, 1);
    assert.equal(placed[0].pos, "E");
    assert.equal(placed[0].ring, 0);
    assert.equal(placed[0].leader, null);
    assert.equal(placed[0].x0, 110);
  }
  // Priority, not the order given: the table's name goes first, the home's after it.
  {
    const scene = { circles: [], width: 200, height: 200 };
    const { placed } = placeLabels([home("home1", 100, 100), table("T1", 100, 100)], scene, measure);
    assert.deepEqual(placed.map((l) => [l.text, l.pos]), [["T1", "E"], ["home1", "W"]]);
  }
  // A label never covers a mark: with a marker right of T1, its name goes up and right.
  {
    const scene = { circles: [{ x: 120, y: 100, r: 7 }], width: 200, height: 200 };
    const { placed } = placeLabels([table("T1", 100, 100)], scene, measure);
    assert.equal(placed[0].pos, "NE");
  }
  // The anchor grows over a robot parked on it: the name beside the robot, not under it.
  {
    const scene = { circles: [{ x: 100, y: 100, r: 7 }, { x: 102, y: 100, r: 12 }], width: 200, height: 200 };
    const { placed } = placeLabels([table("T1", 100, 100)], scene, measure);
    assert.equal(placed[0].ar, 14);
    assert.equal(placed[0].x0, 116);
    checkPlacement({ placed }, scene, "parked");
  }
  // Ring 0 all taken (small marks all around, a line's width apart): the next ring, on a leader
  // line from the mark's edge passing between them.
  {
    const blockers = [];
    for (let a = 0; a < 16; a++) {
      const t = ((a + 0.5) * Math.PI) / 8;
      blockers.push({ x: 100 + 14 * Math.cos(t), y: 100 + 14 * Math.sin(t), r: 2.5 });
    }
    const scene = { circles: blockers, width: 300, height: 300 };
    const { placed } = placeLabels([table("T1", 100, 100)], scene, measure);
    assert.equal(placed.length, 1);
    assert.ok(placed[0].ring > 0 && placed[0].leader, JSON.stringify(placed[0]));
    checkPlacement({ placed }, scene, "ring");
    // Fenced in (the marks touching): no line can leave, so no label.
    const fence = blockers.map((c) => ({ ...c, r: 4 }));
    const found = placeLabels([table("T1", 100, 100)], { circles: fence, width: 300, height: 300 }, measure);
    assert.deepEqual(found.dropped, ["place:T1"]);
  }
  // No room at its size: smaller; no room at all: left out, the least important one.
  {
    const scene = { circles: [], width: 36, height: 14 }; // "T10" is 24 px at 12 px (+2), 20 at 10
    const { placed } = placeLabels([{ ...table("T10", 2, 7), r: 1 }], scene, measure);
    assert.equal(placed.length, 1);
    assert.equal(placed[0].size, 10);
    const tight = { circles: [], width: 60, height: 40 };
    const found = placeLabels([home("home1", 20, 20), table("T10", 20, 20)], tight, measure);
    assert.deepEqual(found.placed.map((l) => l.text), ["T10"]);
    assert.deepEqual(found.dropped, ["place:home1"]);
  }
  // A mark not seen (off the map, or under a control laid over it) has no label.
  {
    const scene = { circles: [], rects: [{ x0: 0, y0: 150, x1: 80, y1: 200 }], width: 200, height: 200 };
    const found = placeLabels([table("T1", -5, 50), table("T2", 40, 170), table("T3", 40, 130)], scene, measure);
    assert.deepEqual(found.hidden, ["place:T1", "place:T2"]);
    assert.deepEqual(found.placed.map((l) => l.text), ["T3"]);
    checkPlacement(found, scene, "covered"); // T3's name is not under the control either
  }
  // Labels stay where they were when they still fit there.
  {
    const scene = { circles: [], width: 200, height: 200 };
    const { placed } = placeLabels([table("T1", 100, 100)], scene, measure, new Map([["place:T1", "SW"]]));
    assert.equal(placed[0].pos, "SW");
  }
  // The crowded room, at a phone's zoom and zoomed in: every rule kept, every table named, every
  // robot's label on it.
  for (const scale of [20, 40]) {
    const { labels, scene } = crowdedRoom(scale);
    const found = placeLabels(labels, scene, measure);
    checkPlacement(found, scene, `crowded at ${scale} px/m`);
    const named = new Set(found.placed.map((l) => l.key));
    for (const l of labels) {
      if (l.kind === "table" || l.kind === "robot") assert.ok(named.has(l.key), `${scale} px/m: ${l.text} left out (${found.dropped})`);
    }
    const r1 = found.placed.find((l) => l.key === "robot:r1");
    assert.equal(r1.text, "r1 → T5");
    // Placed again from its own result: the same positions (nothing jumps from frame to frame).
    const again = placeLabels(labels, scene, measure, new Map(found.placed.map((l) => [l.key, l.pos])));
    assert.deepEqual(again.placed.map((l) => [l.key, l.x0, l.y0]), found.placed.map((l) => [l.key, l.x0, l.y0]));
  }
  // The leader line's test against a box.
  const box = { x0: 10, y0: 10, x1: 20, y1: 20 };
  assert.ok(segmentHitsBox([0, 15, 30, 15], box));
  assert.ok(!segmentHitsBox([0, 0, 30, 5], box));
  assert.ok(!segmentHitsBox([0, 10, 30, 10], box)); // along its edge only
  assert.ok(segmentHitsBox([15, 15, 40, 40], box));
}

function bench() {
  const { labels, scene } = crowdedRoom(20);
  const runs = 2000;
  let previous = null;
  for (let i = 0; i < 200; i++) previous = new Map(placeLabels(labels, scene, measure, previous).placed.map((l) => [l.key, l.pos]));
  // CPU time, not the wall clock: on a shared machine the wall clock counts other processes' turns.
  const t0 = process.cpuUsage();
  const w0 = performance.now();
  for (let i = 0; i < runs; i++) {
    // A robot moves a little each frame, as when one drives.
    labels[30].x = 34 + (i % 40);
    previous = new Map(placeLabels(labels, scene, measure, previous).placed.map((l) => [l.key, l.pos]));
  }
  const used = process.cpuUsage(t0);
  const ms = (used.user + used.system) / 1000 / runs;
  const wall = (performance.now() - w0) / runs;
  console.log(JSON.stringify({ labels: labels.length, marks: scene.circles.length, cpu_ms_per_frame: Number(ms.toFixed(4)), wall_ms_per_frame: Number(wall.toFixed(4)) }));
}

if (process.argv[2] === "bench") bench();
else {
  tests();
  console.log("ok");
}
