"""A place put by hand lands on the map's free floor, or is refused (issue 30, point 3: the owner
moved T16 to (9999, -50); dishes were still taken for it and the robot sent there needed help).
Over real sockets on the demo restaurant; a robot's own pose is saved as it is."""

from __future__ import annotations

from pathlib import Path

from tests.conftest import restaurant


async def test_a_place_off_the_floor_is_refused_and_changes_nothing(tmp_path: Path) -> None:
    async with restaurant(tmp_path) as r:
        c = await r.client()
        await c.subscribe("waypoints", "robots")
        before = dict(c.records["waypoints"]["T16"])
        off = [(9999.0, -50.0, "outside_map"), (-0.6, -0.6, "unknown"), (0.05, 5.0, "occupied")]
        for x, y, reason in off:
            err = await c.error(
                "create",
                "unreachable",
                type="waypoint",
                name="T16",
                x=x,
                y=y,
                kind="table",
                replace=True,
            )
            assert err["details"] == {"x": x, "y": y, "reason": reason}, err
            assert "a place cannot be there" in err["message"]
        assert c.records["waypoints"]["T16"] == before
        stored = {w.name: w for w in await r.app.store.waypoints.list_waypoints()}["T16"]
        assert (stored.x, stored.y) == (before["x"], before["y"])
        # On free floor: moved.
        moved = await c.ok(
            "create",
            type="waypoint",
            name="T16",
            x=before["x"] + 0.2,
            y=before["y"],
            kind="table",
            replace=True,
        )
        assert moved["waypoint"]["x"] == before["x"] + 0.2
        # Where a robot stands is saved as it is (it stood there).
        await c.status("r1", "Ready")
        await c.ok("create", type="waypoint", name="here", robot="r1", kind="other")


async def test_moving_a_blocked_table_clears_its_block(tmp_path: Path) -> None:
    """A table no robot could reach, moved by the owner: the block was about the old spot, so it
    is cleared (its alert with it) and its dishes may leave the pass again. Moved to the same
    spot, or another table moved, nothing is cleared."""
    async with restaurant(tmp_path) as r:
        c = await r.client()
        await c.subscribe("waypoints", "blocks", "alerts")
        assert r.app.core is not None
        service = r.app.core.service
        await service.block("T16", "r1: no way to T16", "r1")
        await service.block("T5", "r1: no way to T5", "r1")
        await c.until(lambda: "T16" in c.records.get("blocks", {}), what="T16 blocked")
        t16 = c.records["waypoints"]["T16"]
        same = {"x": t16["x"], "y": t16["y"], "yaw": t16["yaw"], "kind": "table"}
        await c.ok("create", type="waypoint", name="T16", replace=True, **same)
        assert "T16" in service.blocks  # not moved: still blocked
        await c.ok(
            "create", type="waypoint", name="T16", replace=True, **{**same, "x": t16["x"] + 0.2}
        )
        assert "T16" not in service.blocks and "T5" in service.blocks
        await c.until(lambda: not c.records["blocks"]["T16"]["reason"], what="T16 unblocked")
        blocked = await r.app.store.service.list_blocks()
        assert [b.table for b in blocked] == ["T5"]
