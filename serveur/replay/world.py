"""The world a replay runs in: the map and its waypoints, and the server sized for its clock.

Split from :mod:`serveur.replay.service` because both are settled before the service opens and
neither depends on what happens during it: which map (the demo restaurant or a ROS map with
its waypoints beside it, also read by :mod:`serveur.replay.cli` to check a log's tables and
by :mod:`serveur.replay.report` for the path plots), and how the server's timeouts, message
throttles and rate limit are scaled so that a sped-up or virtual clock means what a real
evening means (:func:`server_config`).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from serveur.replay.client import ReplayError
from serveur.replay.model import ReplayOptions

if TYPE_CHECKING:
    from serveur.core.engine import CoreConfig
    from serveur.maps.mapio import OccupancyMap, Waypoint
    from serveur.security.sessions import SecurityConfig

__all__ = ["load_world", "server_config", "zones_path"]


def load_world(map_path: str | None) -> tuple[OccupancyMap, dict[str, Waypoint], Path]:
    """The grid, the waypoints and the map YAML's path (the demo map when ``map_path`` is None).

    A ROS map's waypoints are ``<stem>_waypoints.json`` (or ``waypoints.json``) beside it.
    """
    from serveur.maps.navigation import demo_map_path, load_demo, load_map, load_waypoints

    if map_path is None:
        grid, wps = load_demo()
        return grid, wps, demo_map_path()
    p = Path(map_path)
    stem = p.with_suffix("")
    for cand in (stem.with_name(stem.name + "_waypoints.json"), p.with_name("waypoints.json")):
        if cand.is_file():
            return load_map(p), load_waypoints(cand), p
    raise ReplayError(f"no waypoints for {p}: expected {stem.name}_waypoints.json beside it")


def zones_path(opts: ReplayOptions) -> Path | None:
    """The zones file the replay creates: ``opts.zones``, else ``<map stem>_zones.json``
    beside the map if it exists ("" or a missing default: no zones)."""
    if opts.zones is not None:
        return Path(opts.zones) if opts.zones else None
    from serveur.maps.navigation import demo_map_path

    p = Path(opts.map_path) if opts.map_path is not None else demo_map_path()
    stem = p.with_suffix("")
    cand = stem.with_name(stem.name + "_zones.json")
    return cand if cand.is_file() else None


def server_config(opts: ReplayOptions, policy: str) -> tuple[CoreConfig, SecurityConfig]:
    """The server's settings for a replay at ``opts.time_scale`` (None: virtual time)."""
    from serveur.core.engine import CoreConfig
    from serveur.security.sessions import SecurityConfig

    # Link timeouts are simulated seconds: at high time scales a 20 ms pause of the event
    # loop (or of the whole process, on a shared machine) is many simulated seconds, so
    # they are kept at >= 2 s of wall time. Nothing here fails on purpose, so they only
    # need to never fire spuriously. Virtual time has no jitter: scale 1.
    scale = opts.time_scale or 1.0
    heartbeat = max(1.0, 2.0 * scale)
    # Accelerated, the replay's cost is rosbridge traffic (~16 messages a robot-second,
    # encoded by the simulator, decoded by the links): nobody watches poses (distances
    # come from the simulator's true poses) and status is only a heartbeat and goal acks,
    # so both are throttled (ms of simulated time) — 2 Hz poses leave the server's arrival
    # checks a pose at most 0.35 m old; status keeps 4 beats per heartbeat period — and
    # the battery, which the server only reports when it moves by 1 %, every 30 s.
    fast = scale >= 10.0 or opts.time_scale is None
    cfg = CoreConfig(
        capacity=opts.capacity,
        policy=policy,
        heartbeat=heartbeat,
        ack_timeout=max(2.0, 2.0 * scale),
        # Saved poses are for a crash restart, which a replay never does: every 5 min.
        pose_persist_period=300.0 if opts.time_scale is None else max(5.0, 0.5 * scale),
        moving_pose_ms=500 if fast else 0,
        status_ms=int(min(1000.0, 250.0 * heartbeat)) if fast else 0,
        battery_ms=30_000 if fast else 0,  # 1 % of charge takes minutes
        # As a site runs: a trip waits at the pass until the replay's staff press Go, and a
        # robot nobody collects from moves on after the timeout (simulated s; None: never).
        auto_depart=False,
        table_timeout=opts.table_timeout,
        leases=opts.leases,
    )
    # The per-connection rate limit counts wall seconds, but the replay's one client
    # speaks for a whole kitchen and staff in accelerated time: at 200x a rush is
    # hundreds of requests a wall second. Scaled, the limit holds in simulated time.
    # In virtual time a whole service's requests come in half a minute of wall time.
    security = SecurityConfig(
        # Nobody revokes the replay's token from another process: look every 5 min.
        sweep_every=300.0,
        rate=50.0 * (max(1.0, scale) if opts.time_scale else 1000.0),
        burst=200.0 * (max(1.0, scale) if opts.time_scale else 1000.0),
    )
    return cfg, security
