"""What a replay writes: ``report.json``, ``summary.txt`` and PNG plots drawn with Pillow.

Why Pillow and not matplotlib: Pillow is already a dependency (it reads the map images), so
``serveur replay`` plots out of the box with no optional extra, no GUI backend to configure
and no font cache to build on first run; the map *is* an image, so drawing robot paths onto
it is natural; and three simple charts (histogram, scatter, paths) need no more than lines,
rectangles and text. Output is byte-identical for identical inputs (no timestamps embedded).

Plots, one set per policy: ``<policy>-wait-hist.png`` (waits in 15 s bins),
``<policy>-waits.png`` (each dish's wait against when it was first ready, with a rolling mean;
a ring for a dish returned from its table and sent again) and
``<policy>-paths.png`` (every robot's path on the map, one colour per robot) and
``<policy>-traffic.png`` (where robots waited: the zones drawn, each wait for a zone a blue
disc at the waiting robot, its area growing with the seconds waited; deadlocks red crosses,
goals aborted because of another robot red rings, conflicts orange dots).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING, Any

from PIL import Image, ImageDraw, ImageFont

from serveur.replay.model import CALL_KINDS

if TYPE_CHECKING:
    from serveur.replay.model import PolicyResult, ReplayOptions

__all__ = ["summary_text", "write_outputs", "write_plots"]

_W, _H = 900, 480
_M = (70, 40, 30, 60)  # left, top, right, bottom margins
_COLOURS = (
    (31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
    (140, 86, 75), (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207),
)  # fmt: skip
_POLICY_COLOUR = {"baseline": (214, 39, 40), "serveur": (31, 119, 180)}


def _font(size: int = 14) -> Any:
    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1 has only the small bitmap font
        return ImageFont.load_default()


def _nice_step(span: float, ticks: int = 6) -> float:
    raw = max(span, 1e-9) / ticks
    mag = 10.0 ** math.floor(math.log10(raw))
    return float(next(m * mag for m in (1, 2, 5, 10) if m * mag >= raw))


class _Axes:
    """A plot area with linear x and y scales, ticks and labels."""

    def __init__(self, title: str, xlabel: str, ylabel: str, xmax: float, ymax: float) -> None:
        self.img = Image.new("RGB", (_W, _H), "white")
        self.d = ImageDraw.Draw(self.img)
        self.xmax, self.ymax = max(xmax, 1e-9), max(ymax, 1e-9)
        left, top, right, bottom = _M
        self.x0, self.y0, self.x1, self.y1 = left, _H - bottom, _W - right, top
        f = _font(16)
        self.d.text((_W / 2, 8), title, fill="black", font=f, anchor="ma")
        self.d.text((_W / 2, _H - 22), xlabel, fill="black", font=_font(), anchor="ma")
        self.d.text((8, top - 22), ylabel, fill="black", font=_font())
        self.d.rectangle((self.x0, self.y1, self.x1, self.y0), outline="black")
        for axis, vmax in (("x", self.xmax), ("y", self.ymax)):
            step = _nice_step(vmax)
            v = 0.0
            while v <= vmax + 1e-9:
                label = f"{v:g}"
                if axis == "x":
                    px = self.px(v, 0)[0]
                    self.d.line((px, self.y0, px, self.y0 + 5), fill="black")
                    self.d.text((px, self.y0 + 8), label, fill="black", font=_font(), anchor="ma")
                else:
                    py = self.px(0, v)[1]
                    self.d.line((self.x0 - 5, py, self.x0, py), fill="black")
                    self.d.line((self.x0, py, self.x1, py), fill=(230, 230, 230))
                    self.d.text((self.x0 - 8, py), label, fill="black", font=_font(), anchor="rm")
                v += step

    def px(self, x: float, y: float) -> tuple[float, float]:
        return (
            self.x0 + (self.x1 - self.x0) * x / self.xmax,
            self.y0 - (self.y0 - self.y1) * y / self.ymax,
        )

    def save(self, path: Path) -> None:
        self.img.save(path, format="PNG", optimize=False)


def _hist(result: PolicyResult, path: Path) -> None:
    waits = result.waits()
    bin_s = 15.0
    top = max(waits, default=0.0)
    nbins = max(1, math.ceil((top + 1e-9) / bin_s))
    counts = [0] * nbins
    for w in waits:
        counts[min(nbins - 1, int(w // bin_s))] += 1
    mean = sum(waits) / len(waits) if waits else 0.0
    ax = _Axes(
        f"{result.policy}: wait per dish, ready -> collected (mean {mean:.0f} s, "
        f"{len(waits)} dishes)",
        "wait (s), 15 s bins",
        "dishes",
        nbins * bin_s,
        max(counts, default=1) * 1.1,
    )
    colour = _POLICY_COLOUR.get(result.policy, _COLOURS[0])
    for i, c in enumerate(counts):
        if c:
            a, b = ax.px(i * bin_s, c), ax.px((i + 1) * bin_s, 0)
            ax.d.rectangle((a[0] + 1, a[1], b[0] - 1, b[1]), fill=colour, outline="black")
    mx = ax.px(mean, 0)[0]
    ax.d.line((mx, ax.y0, mx, ax.y1), fill="black", width=2)
    ax.save(path)


def _over_time(result: PolicyResult, path: Path) -> None:
    done = [o for o in result.orders if o["wait"] is not None]
    pts = sorted((o["ready_at"] / 60.0, o["wait"]) for o in done)
    back = {(o["ready_at"] / 60.0, o["wait"]) for o in done if o.get("returned")}
    tmax = max((p[0] for p in pts), default=1.0)
    wmax = max((p[1] for p in pts), default=1.0)
    ax = _Axes(
        f"{result.policy}: waits (dot: a dish, ring: returned and sent again, "
        "line: mean of the last 20)",
        "dish first ready at (minutes from opening)",
        "wait (s)",
        tmax * 1.02,
        wmax * 1.1,
    )
    colour = _POLICY_COLOUR.get(result.policy, _COLOURS[0])
    for t, w in pts:
        x, y = ax.px(t, w)
        if (t, w) in back:
            ax.d.ellipse((x - 4, y - 4, x + 4, y + 4), outline="black", width=2)
        else:
            ax.d.ellipse((x - 2, y - 2, x + 2, y + 2), fill=colour)
    line: list[tuple[float, float]] = []
    for i in range(len(pts)):
        window = pts[max(0, i - 19) : i + 1]
        line.append(ax.px(pts[i][0], sum(w for _, w in window) / len(window)))
    if len(line) > 1:
        ax.d.line(line, fill="black", width=2)
    ax.save(path)


def _map_image(grid: Any) -> tuple[Image.Image, Any]:
    """The map as an RGB image about 900 px wide, and metres -> pixels."""
    import numpy as np

    g = np.asarray(grid.grid)
    shade = np.where(g < 0, 205, np.where(g >= 50, 60, 255)).astype(np.uint8)
    img = Image.fromarray(shade[::-1], mode="L").convert("RGB")
    scale = max(1, round(900 / grid.width))
    img = img.resize((grid.width * scale, grid.height * scale), Image.Resampling.NEAREST)
    res, (ox, oy) = grid.resolution, grid.origin[:2]

    def px(x: float, y: float) -> tuple[float, float]:
        return ((x - ox) / res * scale, (grid.height - (y - oy) / res) * scale)

    return img, px


def _waypoint_marks(d: Any, px: Any, waypoints: dict[str, Any]) -> None:
    for w in waypoints.values():
        x, y = px(w.x, w.y)
        colour = (0, 0, 0, 255) if w.kind == "table" else (0, 120, 0, 255)
        d.ellipse((x - 4, y - 4, x + 4, y + 4), outline=colour, width=2)
        d.text((x + 6, y - 6), w.name, fill=colour, font=_font(12))


def _paths(result: PolicyResult, grid: Any, waypoints: dict[str, Any], path: Path) -> None:
    img, px = _map_image(grid)
    d = ImageDraw.Draw(img, "RGBA")
    for i, name in enumerate(sorted(result.paths)):
        pts = [px(x, y) for x, y in result.paths[name]]
        r, gr, b = _COLOURS[i % len(_COLOURS)]
        if len(pts) > 1:
            d.line(pts, fill=(r, gr, b, 60), width=3)
        dist = next((rb["distance"] for rb in result.robots if rb["name"] == name), 0.0)
        d.text((10, 10 + 18 * i), f"{name}: {dist:.0f} m", fill=(r, gr, b, 255), font=_font())
    _waypoint_marks(d, px, waypoints)
    d.text(
        (img.width / 2, img.height - 22),
        f"{result.policy}: robot paths ({len(result.trips)} trips)",
        fill=(0, 0, 0, 255),
        font=_font(16),
        anchor="ma",
    )
    img.save(path, format="PNG", optimize=False)


def _traffic(result: PolicyResult, grid: Any, waypoints: dict[str, Any], path: Path) -> None:
    """Where robots waited: zones, waits for them, deadlocks, aborts and conflicts."""
    img, px = _map_image(grid)
    d = ImageDraw.Draw(img, "RGBA")
    per_m = abs(px(1.0, 0.0)[0] - px(0.0, 0.0)[0])
    for z in result.zones:
        pts = [px(x, y) for x, y in z["points"]]
        d.polygon(pts, fill=(255, 200, 0, 70), outline=(200, 140, 0, 255))
        cx = sum(p[0] for p in pts) / len(pts)
        cy = sum(p[1] for p in pts) / len(pts)
        d.text((cx, cy), f"{z['name']} ({z['capacity']})", fill=(120, 80, 0, 255),
               font=_font(12), anchor="mm")  # fmt: skip
    for w in result.wait_places:
        x, y = px(w["x"], w["y"])
        # area proportional to the wait: a 60 s wait is a disc 1 m across
        r = max(4.0, 0.5 * per_m * math.sqrt(max(0.0, w["s"]) / 60.0))
        d.ellipse(
            (x - r, y - r, x + r, y + r), fill=(31, 119, 180, 50), outline=(31, 119, 180, 160)
        )
    t = result.traffic
    for c in t.get("conflicts", []):
        x, y = px(c["x"], c["y"])
        d.ellipse((x - 3, y - 3, x + 3, y + 3), fill=(255, 127, 14, 220))
    for a in t.get("aborts", []):
        if a.get("by_robot"):
            x, y = px(a["x"], a["y"])
            d.ellipse((x - 7, y - 7, x + 7, y + 7), outline=(214, 39, 40, 255), width=2)
    for k in t.get("deadlocks", []):
        x, y = px(k["x"], k["y"])
        d.line((x - 7, y - 7, x + 7, y + 7), fill=(214, 39, 40, 255), width=3)
        d.line((x - 7, y + 7, x + 7, y - 7), fill=(214, 39, 40, 255), width=3)
    _waypoint_marks(d, px, waypoints)
    zw = result.zone_waits
    lines = [
        f"zone waits: {zw.get('waits', 0)}, {zw.get('seconds', 0.0):.0f} s "
        "(blue: where, area ~ seconds)",
        f"deadlocks (red x): {len(t.get('deadlocks', []))}; goals aborted by another robot "
        f"(red ring): {t.get('aborted_by_robot', 0)}",
        f"conflicts (orange, < {t.get('conflict_distance', 0.45):g} m): "
        f"{len(t.get('conflicts', []))}",
    ]
    width = max(d.textlength(text, font=_font()) for text in lines)
    d.rectangle((4, 4, 16 + width, 14 + 18 * len(lines)), fill=(255, 255, 255, 220))
    for i, text in enumerate(lines):
        d.text((10, 8 + 18 * i), text, fill=(0, 0, 0, 255), font=_font())
    d.text(
        (img.width / 2, img.height - 22),
        f"{result.policy}: where robots waited",
        fill=(0, 0, 0, 255),
        font=_font(16),
        anchor="ma",
    )
    img.save(path, format="PNG", optimize=False)


def write_plots(results: dict[str, PolicyResult], map_path: str | None, out: Path) -> list[Path]:
    """Every plot of every policy into ``out``; the files written."""
    from serveur.replay.world import load_world

    grid, waypoints, _ = load_world(map_path)
    written: list[Path] = []
    for name, r in results.items():
        files: Sequence[tuple[str, Any]] = (
            ("wait-hist", lambda p, r=r: _hist(r, p)),
            ("waits", lambda p, r=r: _over_time(r, p)),
            ("paths", lambda p, r=r: _paths(r, grid, waypoints, p)),
            ("traffic", lambda p, r=r: _traffic(r, grid, waypoints, p)),
        )
        for suffix, draw in files:
            p = out / f"{name}-{suffix}.png"
            draw(p)
            written.append(p)
    return written


# -- reporting ---------------------------------------------------------------------------------


def _fmt_s(v: float) -> str:
    return "-" if not math.isfinite(v) else f"{round(v):d} s"


def _robot_cell(r: dict[str, Any], zone_wait: dict[str, float]) -> str:
    return (
        f"{round(r['distance']):d} m / {round(r['busy'] / 60):d} min / "
        f"{round(zone_wait.get(r['name'], 0.0)):d} s"
    )


def summary_text(results: dict[str, PolicyResult], source: str, opts: ReplayOptions) -> str:
    """The short report, policies side by side; times in whole seconds, distances in metres."""
    names = list(results)
    stats = {n: results[n].stats() for n in names}
    rows: list[tuple[str, list[str]]] = [
        ("orders", [str(stats[n]["orders"]) for n in names]),
        ("undelivered", [str(stats[n]["undelivered"]) for n in names]),
        ("wait mean", [_fmt_s(stats[n]["wait_mean"]) for n in names]),
        ("wait p50", [_fmt_s(stats[n]["wait_p50"]) for n in names]),
        ("wait p95", [_fmt_s(stats[n]["wait_p95"]) for n in names]),
        ("wait max", [_fmt_s(stats[n]["wait_max"]) for n in names]),
        ("lower bound mean", [_fmt_s(stats[n]["lower_bound_mean"]) for n in names]),
        ("wait / lower bound", [f"{stats[n]['gap_to_lower_bound']:.1f}x" for n in names]),
        ("trips", [str(stats[n]["trips"]) for n in names]),
        (
            "nav errors / staff rescues",
            [f"{stats[n]['nav_errors']} / {stats[n]['recoveries']}" for n in names],
        ),
        (
            "peak-hour fleet utilisation",
            [f"{100 * stats[n]['peak_utilisation']:.0f} %" for n in names],
        ),
        ("dishes per trip", [f"{stats[n]['dishes_per_trip']:.1f}" for n in names]),
        ("tables per trip", [f"{stats[n]['tables_per_trip']:.1f}" for n in names]),
        (
            "loading at the pass: total / per trip",
            [
                f"{round(stats[n]['loading_s'] / 60):d} min / "
                f"{round(stats[n]['loading_per_trip']):d} s"
                for n in names
            ],
        ),
        (
            "dishes put on a trip still loading",
            [str(stats[n].get("joined", 0)) for n in names],
        ),
        ("table timeouts", [str(stats[n]["table_timeouts"]) for n in names]),
        (
            "dishes returned / re-sent",
            [f"{stats[n]['returned']} / {stats[n]['resent']}" for n in names],
        ),
        (
            f"conflicts (< {opts.conflict_distance:g} m)",
            [str(stats[n]["conflicts"]) for n in names],
        ),
        (
            f"deadlocks (>= {opts.deadlock_after:g} s)",
            [str(stats[n]["deadlocks"]) for n in names],
        ),
        (
            "goals aborted: other robot / other",
            [f"{stats[n]['aborted_by_robot']} / {stats[n]['aborted_other']}" for n in names],
        ),
        (
            "closest two robots came",
            [
                "-" if stats[n]["closest_m"] is None else f"{stats[n]['closest_m']:.2f} m"
                for n in names
            ],
        ),
        (
            "zone waits: count / total",
            [f"{stats[n]['zone_waits']} / {_fmt_s(stats[n]['zone_wait_s'])}" for n in names],
        ),
    ]
    # Robots busiest first, not by name: which of two equal robots took a trip depends on
    # which came home a few milliseconds earlier, and the summary should not flip with that.
    ranked = {n: sorted(results[n].robots, key=lambda r: (-r["busy"], r["name"])) for n in names}
    for i in range(max(len(r) for r in ranked.values())):
        rows.append(
            (
                f"robot #{i + 1}: distance / busy / zone wait",
                [
                    _robot_cell(ranked[n][i], stats[n]["zone_wait_per_robot"])
                    if i < len(ranked[n])
                    else "-"
                    for n in names
                ],
            )
        )
    width = max(len(r[0]) for r in rows) + 2
    colw = max(14, *(len(v) + 2 for _, vals in rows for v in vals))
    lines = [
        f"serveur replay of {source}: {stats[names[0]]['orders']} dishes, {opts.robots} robots, "
        f"seed {opts.seed}, capacity {opts.capacity} tables",
        "wait = dish first ready at the pass -> guest pressed Food collected (server's records;",
        "a dish returned from a table and re-sent counts from its first ready time);",
        "lower bound = path home->table at max speed + the dish's own guest dwell (no loading).",
        f"Loading: {opts.load_fixed:g} s + {opts.load_per_dish:g} s a plate (spread "
        f"{opts.load_spread:g}); parties away: {100 * opts.away:g} %; table timeout: "
        + ("off" if opts.table_timeout is None else f"{opts.table_timeout:g} s")
        + ".",
        "Traffic: robots "
        + ("see each other" if opts.robots_see_each_other else "pass through each other")
        + "; zones: "
        + (", ".join(z["name"] for z in results[names[0]].zones) or "none")
        + "; leases "
        + ("on" if opts.leases else "off")
        + ".",
        *(
            [
                "Guests call (plates, waiter, bill) and bussing robots clear the plates: the "
                "figures above are",
                "that service's (trips: deliveries). The same service with deliveries alone is "
                "beside it below.",
            ]
            if opts.calls
            else []
        ),
        "",
        " " * width + "".join(f"{n:>{colw}}" for n in names),
    ]
    lines += [f"{k:<{width}}" + "".join(f"{v:>{colw}}" for v in vals) for k, vals in rows]
    if "baseline" in stats and "serveur" in stats:
        b, s = stats["baseline"]["wait_mean"], stats["serveur"]["wait_mean"]
        if b > 0 and math.isfinite(s):
            lines += ["", f"serveur mean wait vs baseline: {round(100 * (s - b) / b):+d} %"]
    if opts.calls:
        lines += ["", *_modes_text(results, opts)]
    return "\n".join(lines) + "\n"


def _three(values: Sequence[float]) -> str:
    return " / ".join(_fmt_s(v) for v in values)


def _modes_text(results: dict[str, PolicyResult], opts: ReplayOptions) -> list[str]:
    """Waits per mode: each policy's service with calls and bussing, and alone."""
    names = list(results)
    modes = {n: results[n].modes() for n in names}
    cols: list[tuple[str, str]] = []  # (policy, "calls" | "alone")
    for n in names:
        cols.append((n, "calls"))
        if results[n].alone is not None:
            cols.append((n, "alone"))

    def waits(n: str, mode: str) -> dict[str, Any]:
        w = modes[n]["dish_waits"]["calls_and_bussing" if mode == "calls" else "deliveries_alone"]
        return dict(w)

    def calls_only(fn: Any) -> list[str]:
        return [fn(modes[n]) if mode == "calls" else "-" for n, mode in cols]

    rows: list[tuple[str, list[str]]] = [
        (f"dish wait {k}", [_fmt_s(waits(n, mode)[k]) for n, mode in cols])
        for k in ("mean", "p50", "p95", "max")
    ]
    rows.append(("dishes undelivered", [str(waits(n, mode)["undelivered"]) for n, mode in cols]))
    rows.append(
        (
            "calls: plates / waiter / bill",
            calls_only(lambda m: " / ".join(str(m["calls"][k]["calls"]) for k in CALL_KINDS)),
        )
    )
    rows.append(
        (
            "plates answered: robot / staff / open",
            calls_only(
                lambda m: (
                    f"{m['calls']['plates']['by_robot']} / "
                    f"{m['calls']['plates']['by_staff']} / {m['calls']['plates']['open']}"
                )
            ),
        )
    )
    for k in CALL_KINDS:
        rows.append(
            (
                f"time to answer {k}: p50 / p90 / max",
                calls_only(
                    lambda m, k=k: _three(
                        [m["calls"][k][f"answer_{q}"] for q in ("p50", "p90", "max")]
                    )
                ),
            )
        )
    rows.append(("calls escalated (past call_escalate)", calls_only(lambda m: str(m["escalated"]))))
    rows.append(
        (
            "bussing trips: done / sent",
            calls_only(lambda m: f"{m['bussing']['done']} / {m['bussing']['trips']}"),
        )
    )
    rows.append(
        (
            "plates call -> robot at table: p50 / p90 / max",
            calls_only(
                lambda m: _three(
                    [m["bussing"][f"call_to_robot_{q}"] for q in ("p50", "p90", "max")]
                )
            ),
        )
    )
    rows.append(
        (
            "robots on bussing trips (taken -> emptied)",
            calls_only(lambda m: f"{m['bussing']['robot_s'] / 60:.1f} min"),
        )
    )
    width = max(len(r[0]) for r in rows) + 2
    colw = max(16, *(len(v) + 2 for _, vals in rows for v in vals))
    dish_return = next((m["dish_return"] for m in modes.values() if m["dish_return"]), None)
    out = [
        f"Calls and bussing: once served, {100 * opts.call_plates:g} % of parties call for their "
        "plates to be cleared",
        f"{opts.eat[0] / 60:g}-{opts.eat[1] / 60:g} min after their last dish, "
        f"{100 * opts.call_waiter:g} % call a waiter during the meal, "
        f"{100 * opts.call_bill:g} % the bill.",
        "Staff answer waiter and bill calls; bussing robots take the plates to "
        f"{dish_return or 'the dish return'!r}.",
        "Times to answer and from a plates call to the robot at the table: the server's records.",
        "Dish waits (ready -> collected) beside the same service with deliveries alone:",
        "",
        " " * width + "".join(f"{n:>{colw}}" for n, _ in cols),
        " " * width
        + "".join(
            f"{'calls+bussing' if mode == 'calls' else 'deliveries alone':>{colw}}"
            for _, mode in cols
        ),
    ]
    out += [f"{k:<{width}}" + "".join(f"{v:>{colw}}" for v in vals) for k, vals in rows]
    return out


def _report(results: dict[str, PolicyResult], source: str, opts: ReplayOptions) -> dict[str, Any]:
    return {
        "log": source,
        "options": asdict(opts),
        "policies": {
            name: {
                "summary": r.stats(),
                "robots": r.robots,
                "trips": r.trips,
                "orders": r.orders,
                "sim_seconds": r.sim_seconds,
                "wall_seconds": r.wall_seconds,
                "players": r.players,
                "traffic": r.traffic,
                "zone_waits": r.zone_waits,
                "wait_places": r.wait_places,
                "zones": r.zones,
                **(_modes_report(r) if opts.calls else {}),
            }
            for name, r in results.items()
        },
    }


def _modes_report(r: PolicyResult) -> dict[str, Any]:
    """Calls and bussing: the waits per mode, every call and bussing trip, the same
    service with deliveries alone."""
    alone = r.alone
    return {
        "modes": r.modes(),
        "calls": r.calls,
        "bussing": r.bussing,
        "callers": r.callers,
        "alone": None
        if alone is None
        else {
            "summary": alone.stats(),
            "orders": alone.orders,
            "trips": alone.trips,
            "robots": alone.robots,
            "sim_seconds": alone.sim_seconds,
            "wall_seconds": alone.wall_seconds,
        },
    }


def write_outputs(
    results: dict[str, PolicyResult], source: str, opts: ReplayOptions, out: Path
) -> str:
    """report.json, summary.txt and the plots into ``out``; returns the summary text."""
    out.mkdir(parents=True, exist_ok=True)
    text = summary_text(results, source, opts)
    report = _report(results, source, opts)
    (out / "report.json").write_text(
        json.dumps(_finite(report), indent=1, allow_nan=False) + "\n", encoding="utf-8"
    )
    (out / "summary.txt").write_text(text, encoding="utf-8")
    write_plots(results, opts.map_path, out)
    return text


def _finite(v: Any) -> Any:
    """NaN and infinities (no dish delivered) as null: report.json stays standard JSON."""
    if isinstance(v, float):
        return v if math.isfinite(v) else None
    if isinstance(v, dict):
        return {k: _finite(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_finite(x) for x in v]
    return v
