"""Issue 31, deliver 2: serveur's online waits against a clairvoyant plan of the same service.

For each rate, the order log ``serveur replay`` is given (the same generator, tables, hours
and seed as ``serveur orders``, line numbers as in its CSV, so every seeded dwell, loading
spread and absence is the replay's) is solved offline by OR-Tools *knowing every dish's ready
time in advance* (:mod:`bench.clairvoyant_model`: the problem, its rules, the VRP, the bound).
serveur's figures come from ``serveur replay``'s report.json of the same log, seed and fleet
(``--run-replay`` runs it, with robots that see each other; ``--replay-dir`` reads earlier
runs). It prints, per rate: serveur's mean and 95th-percentile waits, the clairvoyant plan's,
their ratio, the true lower bound, and what the plans do that serveur does not.

The clairvoyant plan is an *upper* bound on the clairvoyant optimum (a heuristic's feasible
plan, in rolling windows) and the lower bound is below it, so serveur's true ratio to the best
clairvoyant schedule lies between serveur / plan (shown first: it never flatters serveur's
distance from the best, it understates it) and serveur / lower bound.

Travel in the plan is the planner's path (the server's distance table) at an effective
speed and a fixed cost per leg (``--speed``, ``--leg``; default 0.6 m/s and 2.5 s, the values
``bench/policy_model.py`` calibrated on replays, checked here against the replay's own legs);
the lower bound uses the robots' top speed and no leg cost.

Needs OR-Tools, a benchmark dependency only: ``python3 -m pip install -e '.[bench]'`` (or
``python3 -m pip install ortools``). Run (the figures in docs/performance.md: the replays
first, each ``serveur replay rR.csv --robots 3 --seed 7 --policy serveur
--robots-see-each-other --out rd/rR`` on the CSVs this script writes, then):

    flock /tmp/bench.lock python3 bench/clairvoyant.py --replay-dir rd --speed 0.65 \\
        --leg 2.5 --window 600 --overlap 300 --time-limit 6 --out clair-out

(``--run-replay`` does both in one go, but takes longer than one locked run should.)

``--rates``, ``--tables``, ``--hours``, ``--seed``, ``--robots`` as ``serveur orders`` and
``serveur replay``; ``--window``/``--overlap``/``--time-limit`` size the rolling horizon.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

import itertools

from clairvoyant_model import (
    Instance,
    Travel,
    evaluate,
    lower_bound,
    make_instance,
    plan_service,
)

from serveur.replay.model import ReplayOptions, loading_time, percentile
from serveur.replay.orders import LogOrder, generate_orders, map_tables


@dataclass
class TripView:
    """A trip as both the plan and the replay can describe it: who, when the robot was home
    before it, when it left, and its stops (table, dish indices, delivered at)."""

    robot: str
    home_at: float
    depart: float
    stops: list[tuple[str, list[int]]]


def numbered(log: Sequence[LogOrder]) -> list[LogOrder]:
    """Generated orders with the line each has in its CSV (header = line 1), as the replay
    numbers them (:func:`serveur.replay.service._numbered`): its seeds are keyed by line."""
    return [replace(o, line=i + 2) for i, o in enumerate(log)]


def distance_table() -> tuple[Any, list[str]]:
    """The demo room's path distances (the server's: the same planner, 0.2 m robot radius)."""
    from serveur.maps.navigation import DistanceTable, Planner, load_demo

    grid, wps = load_demo()
    table = DistanceTable(Planner(grid, robot_radius=0.2), wps)
    table.matrix(sorted(wps))
    homes = sorted(w.name for w in wps.values() if w.kind == "home")
    return table, homes


# -- figures ---------------------------------------------------------------------------------


def trip_figures(
    inst: Instance, trips: Sequence[TripView], delivered: dict[int, float]
) -> dict[str, Any]:
    """What a set of trips does, the same way for the plan and for serveur's replay."""
    dishes = inst.dishes
    n = len(trips) or 1
    held = held_other = 0
    hold_s: list[float] = []
    overtaken = 0
    multi = [t for t in trips if len({s for s, _ in t.stops}) > 1]
    hop: list[float] = []
    for t in multi:
        tabs = [s for s, _ in t.stops]
        hop += [inst.distance(a, b) for a, b in itertools.pairwise(tabs)]
    depart_of: dict[int, float] = {}
    for t in trips:
        for _, ids in t.stops:
            for i in ids:
                depart_of[i] = t.depart
    for t in trips:
        ids = [i for _, d in t.stops for i in d]
        if not ids:
            continue
        first = min(ids, key=lambda i: dishes[i].ready)
        lastd = max(ids, key=lambda i: dishes[i].ready)
        hold = dishes[lastd].ready - max(t.home_at, dishes[first].ready)
        if hold > 1.0 and len(ids) > 1:
            held += 1
            hold_s.append(hold)
            if dishes[lastd].table != dishes[first].table:
                held_other += 1
        # A dish ready before this trip's first, still on the pass when it left: not FIFO.
        r0 = dishes[first].ready
        if any(
            dishes[j].ready < r0 and depart_of.get(j, math.inf) > t.depart
            for j in range(max(0, first - 60), first)
        ):
            overtaken += 1
    batch_trips: dict[int, set[int]] = {}
    for k, t in enumerate(trips):
        for _, ids in t.stops:
            for i in ids:
                batch_trips.setdefault(dishes[i].batch, set()).add(k)
    waits = [delivered[d.idx] - d.ready for d in dishes if d.idx in delivered]
    on_pass = [depart_of[d.idx] - d.ready for d in dishes if d.idx in depart_of]
    after = [delivered[i] - depart_of[i] for i in depart_of if i in delivered]
    return {
        "dishes": len(waits),
        "wait_mean": statistics.fmean(waits),
        "wait_p95": percentile(waits, 95),
        "trips": len(trips),
        "tables_per_trip": sum(len({s for s, _ in t.stops}) for t in trips) / n,
        "dishes_per_trip": sum(len(d) for t in trips for _, d in t.stops) / n,
        "multi_table_share": len(multi) / n,
        "held_share": held / n,
        "held_other_table_share": held_other / n,
        "hold_mean": statistics.fmean(hold_s) if hold_s else 0.0,
        "hop_mean_m": statistics.fmean(hop) if hop else 0.0,
        "not_fifo_share": overtaken / n,
        "batches_split_share": sum(1 for v in batch_trips.values() if len(v) > 1)
        / max(1, len(batch_trips)),
        "on_pass_mean": statistics.fmean(on_pass) if on_pass else math.nan,
        "after_departure_mean": statistics.fmean(after) if after else math.nan,
    }


def plan_trips(inst: Instance, ev: Any) -> list[TripView]:
    return [
        TripView(f"r{rec.robot + 1}", rec.home_at, rec.depart, [(s, list(d)) for s, d in rec.stops])
        for rec in ev.trips
    ]


def replay_trips(inst: Instance, report: dict[str, Any]) -> tuple[list[TripView], dict[int, float]]:
    """serveur's trips from report.json: a trip's robot left home (status out of Awaiting, the
    start of a busy span) then loaded for :func:`loading_time` (the replay's staff's own
    figure) and left; it was home since its previous span's end."""
    pol = report["policies"]["serveur"]
    idx_of = {d.line: d.idx for d in inst.dishes}
    delivered = {
        idx_of[o["line"]]: o["collected"] for o in pol["orders"] if o["collected"] is not None
    }
    by_task: dict[int, list[dict[str, Any]]] = {}
    for o in pol["orders"]:
        if o["task"] is not None:
            by_task.setdefault(o["task"], []).append(o)
    spans = {r["name"]: r["busy_spans"] for r in pol["robots"]}
    out = []
    for t in pol["trips"]:
        if t["status"] != "done" or t["robot"] is None:
            continue
        orders = by_task.get(t["id"], [])
        if not orders:
            continue
        sp = spans.get(t["robot"], [])
        k = max((i for i, s in enumerate(sp) if s[0] <= t["started"] + 1e-6), default=-1)
        if k < 0:  # the trip was given to a robot still out: it left on its return
            k = min(range(len(sp)), key=lambda i: abs(sp[i][0] - t["started"]))
        left = max(sp[k][0], t["started"]) if sp else t["started"]
        home_at = sp[k - 1][1] if k > 0 else 0.0
        load = loading_time(inst.opts, min(o["line"] for o in orders), len(orders))
        stops = []
        for table in t["stops"]:
            ids = [idx_of[o["line"]] for o in orders if o["table"] == table]
            if ids and table not in [s for s, _ in stops]:
                stops.append((table, ids))
        out.append(TripView(t["robot"], home_at, left + load, stops))
    return out, delivered


def leg_check(inst: Instance, report: dict[str, Any]) -> tuple[int, float, float]:
    """The replay's own legs between two stops of one trip (no party away): (count, median of
    real / modelled leg time, median real leg time). Arrival = collected - the stop's dwell."""
    from serveur.replay.model import stop_dwell

    pol = report["policies"]["serveur"]
    by_task: dict[int, list[dict[str, Any]]] = {}
    for o in pol["orders"]:
        if o["task"] is not None and o["collected"] is not None:
            by_task.setdefault(o["task"], []).append(o)
    idx_of = {d.line: d.idx for d in inst.dishes}
    ratios, legs = [], []
    for t in pol["trips"]:
        orders = by_task.get(t["id"], [])
        stops = []
        for table in t["stops"]:
            os_ = [o for o in orders if o["table"] == table]
            if not os_ or any(inst.dishes[idx_of[o["line"]]].back for o in os_):
                stops = []
                break
            dwell = stop_dwell(inst.opts.seed, [o["line"] for o in os_])
            stops.append((table, os_[0]["collected"] - dwell, os_[0]["collected"]))
        for (a, _, left), (b, arrive, _) in itertools.pairwise(stops):
            real = arrive - left
            ratios.append(real / inst.leg(a, b))
            legs.append(real)
    if not ratios:
        return 0, math.nan, math.nan
    return len(ratios), statistics.median(ratios), statistics.median(legs)


# -- the command -----------------------------------------------------------------------------


def run_replay(csv: Path, out: Path, ns: argparse.Namespace) -> dict[str, Any]:
    cmd = [
        "serveur", "replay", str(csv), "--robots", str(ns.robots), "--seed", str(ns.seed),
        "--policy", "serveur", "--robots-see-each-other", "--quiet", "--out", str(out),
    ]  # fmt: skip
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    print(f"  {' '.join(cmd)}: {time.perf_counter() - t0:.0f} s wall", file=sys.stderr)
    return json.loads((out / "report.json").read_text())


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rates", type=float, nargs="+", default=[120, 240, 360, 480, 600])
    ap.add_argument("--tables", type=int, default=12)
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--robots", type=int, default=3)
    ap.add_argument("--speed", type=float, default=0.6, help="plan: effective m/s (0.6)")
    ap.add_argument("--leg", type=float, default=2.5, help="plan: s a leg (2.5)")
    ap.add_argument("--window", type=float, default=900.0, help="rolling horizon step, s")
    ap.add_argument("--overlap", type=float, default=300.0, help="look-ahead past it, s")
    ap.add_argument("--time-limit", type=float, default=20.0, help="OR-Tools s per window")
    ap.add_argument(
        "--unit",
        choices=("batch", "dish", "both"),
        default="both",
        help="VRP unit: kitchen batches, dishes, or batches then dishes from there (both)",
    )
    ap.add_argument("--run-replay", action="store_true", help="run serveur replay first")
    ap.add_argument("--replay-dir", type=Path, help="read <dir>/r<rate>/report.json")
    ap.add_argument("--out", type=Path, default=Path("clair-out"))
    ns = ap.parse_args()

    from serveur.replay.orders import format_orders
    from serveur.sim.kinematics import Limits

    ns.out.mkdir(parents=True, exist_ok=True)
    table, all_homes = distance_table()
    homes = all_homes[: ns.robots]
    tables = map_tables()[: ns.tables]
    opts = ReplayOptions(robots=ns.robots, seed=ns.seed)
    travel = Travel(ns.speed, ns.leg)
    rows: list[dict[str, Any]] = []
    for rate in ns.rates:
        tag = f"r{rate:g}"
        log = numbered(generate_orders(tables, ns.hours, rate, ns.seed))
        csv = ns.out / f"{tag}.csv"
        csv.write_text(format_orders(log))
        inst = make_instance(log, homes, table.distance, travel, opts)
        print(f"{tag}: {len(log)} dishes, {ns.tables} tables, {ns.robots} robots", file=sys.stderr)
        report = None
        if ns.run_replay:
            report = run_replay(csv, ns.out / tag, ns)
        elif ns.replay_dir is not None and (ns.replay_dir / tag / "report.json").is_file():
            report = json.loads((ns.replay_dir / tag / "report.json").read_text())
        if report is not None:
            got = [
                (o["line"], o["table"], o["ready_at"])
                for o in report["policies"]["serveur"]["orders"]
            ]
            want = [(o.line, o.table, o.ready_at) for o in log]
            if sorted(got) != want:
                raise SystemExit(f"{tag}: the replay's log is not this log")
        t0 = time.perf_counter()
        plan = plan_service(
            inst,
            window=ns.window,
            overlap=ns.overlap,
            time_limit=ns.time_limit,
            unit=ns.unit,
            progress=lambda s: print(s, file=sys.stderr),
        )
        solve_s = time.perf_counter() - t0
        ev = evaluate(inst, plan)
        lb = lower_bound(inst, Limits().max_speed)
        row: dict[str, Any] = {
            "rate": rate,
            "dishes": len(log),
            "solve_s": solve_s,
            "plan": trip_figures(inst, plan_trips(inst, ev), ev.delivered),
            "lower_bound_mean": statistics.fmean(lb),
            "lower_bound_p95": percentile(lb, 95),
        }
        if report is not None:
            trips, delivered = replay_trips(inst, report)
            row["serveur"] = trip_figures(inst, trips, delivered)
            s = report["policies"]["serveur"]["summary"]
            row["serveur_summary"] = {
                k: s.get(k) for k in ("wait_mean", "wait_p95", "table_timeouts", "conflicts",
                                      "deadlocks", "peak_utilisation", "loading_per_trip")
            }  # fmt: skip
            row["legs"] = leg_check(inst, report)
        rows.append(row)
        (ns.out / "clairvoyant.json").write_text(json.dumps(rows, indent=1))
        print_row(row)
    print_tables(rows)
    return 0


def print_row(row: dict[str, Any]) -> None:
    p = row["plan"]
    line = (
        f"  plan: mean {p['wait_mean']:.1f} s, p95 {p['wait_p95']:.0f} s, "
        f"{p['trips']} trips, {p['tables_per_trip']:.2f} tables/trip; solved in "
        f"{row['solve_s']:.0f} s; lower bound {row['lower_bound_mean']:.1f} s"
    )
    if "serveur" in row:
        s = row["serveur"]
        line += f"; serveur mean {s['wait_mean']:.1f} s, p95 {s['wait_p95']:.0f} s"
    print(line, file=sys.stderr)


def print_tables(rows: Sequence[dict[str, Any]]) -> None:
    print(
        "| rate (dishes/h) | dishes | serveur mean / p95 | clairvoyant plan mean / p95 "
        "| serveur / plan: mean, p95 | lower bound mean | serveur / bound | plan / bound |"
    )
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        p, lb = r["plan"], r["lower_bound_mean"]
        s = r.get("serveur")
        sm = f"{s['wait_mean']:.1f} / {s['wait_p95']:.0f} s" if s else "-"
        ratio = (
            f"**{s['wait_mean'] / p['wait_mean']:.2f}x**, {s['wait_p95'] / p['wait_p95']:.2f}x"
            if s
            else "-"
        )
        sb = f"{s['wait_mean'] / lb:.2f}x" if s else "-"
        print(
            f"| {r['rate']:g} | {r['dishes']} | {sm} | {p['wait_mean']:.1f} / "
            f"{p['wait_p95']:.0f} s | {ratio} | {lb:.1f} s | {sb} | {p['wait_mean'] / lb:.2f}x |"
        )
    print()
    print(
        "| rate | who | trips | tables / trip | dishes / trip | trips with 2+ tables "
        "| trips held for a dish not ready (for another table's) | mean hold "
        "| kitchen batches split over trips | trips leaving an older dish on the pass "
        "| on the pass / after departure |"
    )
    print("|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        for who in ("plan", "serveur"):
            f = r.get(who)
            if f is None:
                continue
            print(
                f"| {r['rate']:g} | {who} | {f['trips']} | {f['tables_per_trip']:.2f} "
                f"| {f['dishes_per_trip']:.2f} | {100 * f['multi_table_share']:.0f} % "
                f"| {100 * f['held_share']:.0f} % ({100 * f['held_other_table_share']:.0f} %) "
                f"| {f['hold_mean']:.1f} s | {100 * f['batches_split_share']:.0f} % "
                f"| {100 * f['not_fifo_share']:.0f} % "
                f"| {f['on_pass_mean']:.1f} / {f['after_departure_mean']:.1f} s |"
            )
    legs = [r["legs"] for r in rows if "legs" in r]
    if legs:
        print()
        for r in rows:
            if "legs" in r:
                n, ratio, med = r["legs"]
                print(
                    f"rate {r['rate']:g}: {n} table-to-table legs, real / modelled "
                    f"{ratio:.2f} (median), median leg {med:.1f} s"
                )


if __name__ == "__main__":
    raise SystemExit(main())
