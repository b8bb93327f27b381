"""``serveur replay`` on the command line: its options, the run and the report files.

Split from :mod:`serveur.replay.service` so that the service itself stays readable;
:mod:`serveur.cli` registers the subcommand through :func:`add_replay_parser`. The replay and the
report are imported when the command runs.
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Callable
from pathlib import Path

from serveur.replay.client import ReplayError
from serveur.replay.model import POLICIES, ReplayOptions
from serveur.replay.orders import OrderLogError, read_orders

__all__ = ["add_replay_parser"]


def _ros_list(text: str) -> tuple[int, ...]:
    try:
        versions = tuple(int(v) for v in text.split(","))
    except ValueError:
        versions = ()
    if not versions or any(v not in (1, 2) for v in versions):
        raise argparse.ArgumentTypeError(f"--ros wants 1, 2 or a list like 1,2, not {text!r}")
    return versions


def _pair(what: str) -> Callable[[str], tuple[float, float]]:
    """An option's parser for two numbers, ``A,B``."""

    def parse(text: str) -> tuple[float, float]:
        try:
            a, b = (float(v) for v in text.split(","))
        except ValueError:
            msg = f"{what} wants two numbers like 1,2, not {text!r}"
            raise argparse.ArgumentTypeError(msg) from None
        return a, b

    return parse


def _cmd_replay(ns: argparse.Namespace) -> int:
    root = logging.getLogger()
    level = root.level
    if not ns.verbose:  # every status change is logged at INFO: too much for a whole service
        root.setLevel(logging.ERROR)
    try:
        return _replay_command(ns)
    finally:
        root.setLevel(level)


def _replay_command(ns: argparse.Namespace) -> int:
    bad = [
        name
        for name, ok in (
            ("--load-fixed", ns.load_fixed >= 0),
            ("--load-per-dish", ns.load_per_dish >= 0),
            ("--load-spread", ns.load_spread >= 0),
            ("--away", 0 <= ns.away <= 1),
            ("--table-timeout", ns.table_timeout >= 0),
            ("--conflict-distance", ns.conflict_distance > 0),
            ("--deadlock-after", ns.deadlock_after > 0),
            ("--calls-plates", 0 <= ns.calls_plates <= 1),
            ("--calls-waiter", 0 <= ns.calls_waiter <= 1),
            ("--calls-bill", 0 <= ns.calls_bill <= 1),
            ("--eat", 0 <= ns.eat[0] <= ns.eat[1]),
            ("--kitchen-ahead", ns.kitchen_ahead >= 0),
        )
        if not ok
    ]
    if bad:
        print(f"serveur replay: out of range: {', '.join(bad)}", file=sys.stderr)
        return 2
    opts = ReplayOptions(
        robots=ns.robots,
        time_scale=ns.time_scale,
        map_path=ns.map,
        seed=ns.seed,
        capacity=ns.capacity,
        kinematics=ns.kinematics,
        ros=ns.ros,
        hold=ns.hold,
        hold_max=ns.hold_max,
        rank=ns.rank,
        join=not ns.no_join,
        kitchen_ahead=ns.kitchen_ahead,
        load_fixed=ns.load_fixed,
        load_per_dish=ns.load_per_dish,
        load_spread=ns.load_spread,
        away=ns.away,
        table_timeout=ns.table_timeout or None,
        progress=not ns.quiet,
        robots_see_each_other=ns.robots_see_each_other,
        zones="" if ns.zones == "none" else ns.zones,
        leases=not ns.no_leases,
        conflict_distance=ns.conflict_distance,
        deadlock_after=ns.deadlock_after,
        calls=not ns.no_calls,
        call_plates=ns.calls_plates,
        call_waiter=ns.calls_waiter,
        call_bill=ns.calls_bill,
        eat=(60.0 * ns.eat[0], 60.0 * ns.eat[1]),
        dish_return=ns.dish_return,
    )
    from serveur.replay.service import run_replay
    from serveur.replay.traffic import load_zones
    from serveur.replay.world import load_world, zones_path

    try:
        zp = zones_path(opts)
        if zp is not None:
            load_zones(zp)
    except ValueError as exc:
        print(f"serveur replay: {exc}", file=sys.stderr)
        return 2
    try:
        _, waypoints, _ = load_world(ns.map)
        tables = {w.name for w in waypoints.values() if w.kind == "table"}
        orders = read_orders(ns.log, tables=tables)
    except (OrderLogError, ReplayError) as exc:
        print(f"serveur replay: {exc}", file=sys.stderr)
        return 2
    has_return = any(w.kind == "dish_return" for w in waypoints.values())
    if opts.calls and ns.map is not None and not has_return and opts.dish_return is None:
        print(
            f"serveur replay: {ns.map} has no dish return (a waypoint of kind dish_return) for "
            "the bussing robots: add one, say where with --dish-return X,Y, or --no-calls",
            file=sys.stderr,
        )
        return 2
    policies = list(POLICIES) if ns.policy == "both" else [ns.policy]
    try:
        results = run_replay(orders, opts, policies)
    except ReplayError as exc:
        print(f"serveur replay: {exc}", file=sys.stderr)
        return 1
    from serveur.replay.report import write_outputs

    text = write_outputs(results, ns.log, opts, Path(ns.out))
    print(text, end="")
    print(f"report, summary and plots in {ns.out}/")
    runs = [*results.values(), *(r.alone for r in results.values() if r.alone is not None)]
    return 0 if all(r.undelivered == 0 for r in runs) else 1


def add_replay_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register ``serveur replay`` (called once from :mod:`serveur.cli`)."""
    p = sub.add_parser(
        "replay",
        help="replay an order log through the server and simulated robots",
        description="Run the real server and N simulated robots on one accelerated clock, "
        "feed the log's dishes at their times, play staff and guests (who also call for "
        "their plates to be cleared, a waiter and the bill, unless --no-calls: the same "
        "service is then replayed with deliveries alone too, for the waits side by side), "
        "and write report.json, summary.txt and PNG plots to --out. Exit 1 if any dish was "
        "left undelivered.",
    )
    p.add_argument("log", help="order log CSV (ready_at,table,dish)")
    p.add_argument("--robots", type=int, default=3, help="simulated robots (default 3)")
    p.add_argument(
        "--time-scale",
        type=float,
        default=None,
        help="follow the wall clock, this many times faster (default: virtual time, as fast "
        "as the CPU allows and deterministic)",
    )
    p.add_argument("--policy", choices=[*POLICIES, "both"], default="serveur")
    p.add_argument("--map", default=None, help="map YAML (waypoints: <stem>_waypoints.json)")
    p.add_argument("--seed", type=int, default=0, help="robots' and guests' seed (default 0)")
    p.add_argument("--capacity", type=int, default=4, help="tables per tray (default 4)")
    p.add_argument("--kinematics", choices=["omni", "diff"], default="omni")
    p.add_argument(
        "--ros",
        type=_ros_list,
        default=(1,),
        metavar="1|2|1,2",
        help="which ROS the simulated robots run, cycled over them (1,2: a mixed fleet)",
    )
    p.add_argument(
        "--hold",
        type=float,
        default=10.0,
        help="serveur staff: seconds a table may wait for its next dish (default 10)",
    )
    p.add_argument(
        "--hold-max",
        type=float,
        default=60.0,
        help="serveur staff: ... growing to this as tables queue (default 60; = --hold: fixed)",
    )
    p.add_argument(
        "--rank",
        choices=["fifo", "wspt", "best"],
        default="best",
        help="serveur staff: tables first-ready, by plates per robot-second, or the better "
        "(default best)",
    )
    p.add_argument(
        "--no-join",
        action="store_true",
        help="serveur staff: never put a dish on its table's trip still loading at the pass",
    )
    d = ReplayOptions()
    p.add_argument(
        "--kitchen-ahead",
        type=float,
        default=d.lookahead,
        metavar="S",
        help="the kitchen enters each dish in the server this many seconds before it is "
        "ready (ordered, then ready at its time), so that the server knows food is coming "
        "and a bussing trip waits for it (default: when the kitchen display shows it to the "
        f"staff, {d.lookahead:g} s; 0: a dish appears when ready)",
    )
    p.add_argument(
        "--load-fixed",
        type=float,
        default=d.load_fixed,
        help="staff at the pass: seconds to load a trip and press Go, fixed part "
        f"(default {d.load_fixed:g}; an assumption, see docs/performance.md)",
    )
    p.add_argument(
        "--load-per-dish",
        type=float,
        default=d.load_per_dish,
        help=f"... plus this per plate (default {d.load_per_dish:g})",
    )
    p.add_argument(
        "--load-spread",
        type=float,
        default=d.load_spread,
        help="... times a seeded log-normal factor of this sigma "
        f"(default {d.load_spread:g}; 0: always the same)",
    )
    p.add_argument(
        "--away",
        type=float,
        default=d.away,
        help="probability a party is away from its table when its food comes, for 3-12 "
        f"min (default {d.away:g}; seeded)",
    )
    p.add_argument(
        "--table-timeout",
        type=float,
        default=d.table_timeout,
        help="the server's: seconds a robot waits at a table before it goes on and the "
        f"dishes are returned (default {d.table_timeout:g}; 0: wait for ever)",
    )
    p.add_argument(
        "--robots-see-each-other",
        dest="robots_see_each_other",
        action="store_true",
        default=True,
        help="the default: robots' footprints are obstacles to each other in the simulator: "
        "they keep clear, stop short, wait, plan around and abort after a patience",
    )
    p.add_argument(
        "--robots-pass-through",
        dest="robots_see_each_other",
        action="store_false",
        help="robots drive through each other (ghosts: aisles of unlimited width; only to "
        "compare with figures measured that way)",
    )
    p.add_argument(
        "--zones",
        default=None,
        metavar="FILE",
        help='zones created before the service opens ({"zones": [{"name", "points", '
        '"capacity"}]}; default: <map stem>_zones.json beside the map if it exists; '
        "none: no zones)",
    )
    p.add_argument(
        "--no-leases",
        action="store_true",
        help="the server ignores zones (CoreConfig.leases off): robots never wait for them",
    )
    p.add_argument(
        "--conflict-distance",
        type=float,
        default=d.conflict_distance,
        help="a conflict: two robots' centres closer than this, m "
        f"(default {d.conflict_distance:g}: 2 x radius + 5 cm)",
    )
    p.add_argument(
        "--deadlock-after",
        type=float,
        default=d.deadlock_after,
        help="a deadlock: robots with goals, within 1.5 m of each other, none moving 0.1 m "
        f"for this many s (default {d.deadlock_after:g})",
    )
    g = p.add_argument_group(
        "guests' calls and bussing (on by default: each policy's service is then replayed "
        "again with deliveries alone, for the dish waits side by side)"
    )
    g.add_argument(
        "--no-calls",
        action="store_true",
        help="deliveries alone: no guest calls, no bussing robots (one run per policy)",
    )
    g.add_argument(
        "--calls-plates",
        type=float,
        default=d.call_plates,
        metavar="P",
        help="share of parties that call for their plates to be cleared after the meal, "
        f"answered by a bussing robot (default {d.call_plates:g})",
    )
    g.add_argument(
        "--calls-waiter",
        type=float,
        default=d.call_waiter,
        metavar="P",
        help="share of parties that call a waiter once during the meal "
        f"(default {d.call_waiter:g})",
    )
    g.add_argument(
        "--calls-bill",
        type=float,
        default=d.call_bill,
        metavar="P",
        help="share of parties that call for the bill 3-12 min after the meal "
        f"(default {d.call_bill:g})",
    )
    g.add_argument(
        "--eat",
        type=_pair("--eat"),
        default=(d.eat[0] / 60.0, d.eat[1] / 60.0),
        metavar="MIN,MAX",
        help="minutes from a party's last dish collected to its plates call (uniform; "
        f"default {d.eat[0] / 60:g},{d.eat[1] / 60:g})",
    )
    g.add_argument(
        "--dish-return",
        type=_pair("--dish-return"),
        default=None,
        metavar="X,Y",
        help="where the bussing robots are emptied, if the map has no waypoint of kind "
        "dish_return (default in the demo room: beside the pass, 9,10.8)",
    )
    p.add_argument("--out", default="replay-out", help="output directory (default replay-out)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_replay, is_async=False)
