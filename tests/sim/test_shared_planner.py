"""Simulations of the same map in one process share one planner and its distance fields
(serveur.robot_sim.shared_planner); another map, or the same cells elsewhere, get their own."""

from __future__ import annotations

import dataclasses

from serveur.maps.navigation import demo_map_path, load_demo
from serveur.robot_sim import shared_planner, start_simulation


async def test_a_second_simulation_of_the_map_plans_with_the_first_ones_fields() -> None:
    first = await start_simulation(1, port=0, map_path=demo_map_path())
    try:
        planner = first.robots[0].state.planner
        goal = (12.6, 1.6)
        await first.warm_plans([goal])
        computed = planner.fields_computed
    finally:
        await first.close()
    second = await start_simulation(2, port=0, map_path=demo_map_path())
    try:
        assert all(r.state.planner is planner for r in second.robots)
        assert await second.warm_plans([goal]) == 1
        assert planner.fields_computed == computed  # read back, not planned again
    finally:
        await second.close()


def test_the_key_is_the_maps_content() -> None:
    grid, _ = load_demo()
    same = dataclasses.replace(grid)  # another object, the same cells
    moved = dataclasses.replace(grid, origin=(grid.origin[0] + 1.0, grid.origin[1], 0.0))
    a = shared_planner(grid, cache_size=40)
    assert shared_planner(same, cache_size=40) is a
    assert shared_planner(moved, cache_size=40) is not a
