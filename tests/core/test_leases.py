"""The lease rules (serveur.core.leases), without sockets: all-at-once grants, first come first
served, release on leaving, expiry, staff breaking a lease, and robots waiting for each other."""

from __future__ import annotations

from serveur.core.leases import LeaseBook, Zone, path_zones, point_in_polygon, segment_hits_polygon

# A 6 m long, 0.8 m wide aisle along x, and a doorway further on.
AISLE = Zone("aisle", ((0.0, 0.0), (6.0, 0.0), (6.0, 0.8), (0.0, 0.8)))
DOOR = Zone("door", ((8.0, 0.0), (9.0, 0.0), (9.0, 1.0), (8.0, 1.0)))
PASS = Zone("pass", ((0.0, 3.0), (2.0, 3.0), (2.0, 5.0), (0.0, 5.0)), capacity=2)


def book() -> LeaseBook:
    return LeaseBook([AISLE, DOOR, PASS])


def mine(grants: list, robot: str) -> bool:
    return any(g.robot == robot for g in grants)


def test_geometry() -> None:
    assert point_in_polygon((3.0, 0.4), AISLE.points)
    assert point_in_polygon((0.0, 0.4), AISLE.points)  # on an edge: inside
    assert not point_in_polygon((3.0, 1.0), AISLE.points)
    assert segment_hits_polygon((3.0, -1.0), (3.0, 2.0), AISLE.points)  # crosses, no end inside
    assert not segment_hits_polygon((-1.0, 2.0), (7.0, 2.0), AISLE.points)
    path = [(-1.0, 0.4), (7.0, 0.4), (8.5, 2.0)]
    assert path_zones(path, [DOOR, AISLE, PASS]) == ["aisle"]
    assert path_zones([(8.5, -0.5), (8.5, 2.0)], [DOOR, AISLE]) == ["door"]
    # A path 0.15 m beside the aisle: clear for a point, touched for a 0.25 m footprint.
    beside = [(1.0, 0.95), (5.0, 0.95)]
    assert path_zones(beside, [AISLE]) == []
    assert path_zones(beside, [AISLE], margin=0.25) == ["aisle"]


def test_all_at_once_and_first_come_first_served() -> None:
    b = book()
    assert mine(b.request("r1", ["aisle"], 0.0), "r1")
    # r2 needs the aisle and the door: it gets neither while r1 has the aisle (no hold-and-wait).
    assert not mine(b.request("r2", ["aisle", "door"], 1.0), "r2")
    assert b.held("r2") == [] and b.waiting("r2") == ("aisle", "door")
    # r3 wants only the door, free: but r2 asked first for it, so r3 waits too (no overtaking).
    assert not mine(b.request("r3", ["door"], 2.0), "r3")
    assert b.blockers("r3") == ["r2"] and b.blockers("r2") == ["r1"]
    # r1 drives through the aisle and out: the aisle is released, r2 gets both, r3 still waits.
    assert b.moved("r1", 3.0, 0.4) == []
    grants = b.moved("r1", 7.0, 0.4)
    assert [(g.robot, g.zones) for g in grants] == [("r2", ("aisle", "door"))]
    assert b.holders("aisle") == ["r2"] and b.waiting("r3") == ("door",)
    # Robots that share no zone never wait for each other.
    assert mine(b.request("r4", ["pass"], 3.0), "r4")
    assert mine(b.request("r5", [], 3.0), "r5")


def test_capacity_and_release_at_the_end_of_a_leg() -> None:
    b = book()
    assert mine(b.request("r1", ["pass"], 0.0), "r1")
    assert mine(b.request("r2", ["pass"], 0.0), "r2")  # capacity 2
    assert not mine(b.request("r3", ["pass"], 0.0), "r3")
    # r1's leg ends without its pose ever inside the zone (sparse poses): released at leg end.
    grants = b.leg_over("r1", 5.0, 5.5)
    assert [g.robot for g in grants] == ["r3"]
    # r2's leg ends inside the zone: kept until it leaves.
    assert b.leg_over("r2", 1.0, 4.0) == []
    assert b.holders("pass") == ["r2", "r3"]
    b.moved("r2", 3.0, 4.0)
    assert b.holders("pass") == ["r3"]


def test_a_new_leg_gives_up_the_old_leases_it_does_not_ask_again() -> None:
    b = book()
    assert mine(b.request("r1", ["aisle", "door"], 0.0), "r1")
    assert not mine(b.request("r2", ["door"], 1.0), "r2")
    grants = b.request("r1", ["aisle"], 2.0)  # sent elsewhere before passing the door
    assert {g.robot for g in grants} == {"r1", "r2"} and b.holders("door") == ["r2"]


def test_expiry_break_and_zones_redrawn() -> None:
    b = book()
    b.request("r1", ["aisle"], 0.0)
    b.request("r2", ["aisle"], 1.0)
    assert [g.robot for g in b.expire("r1")] == ["r2"]  # Offline: its lease ends
    b.request("r3", ["aisle"], 2.0)
    broken, grants = b.break_lease("aisle")
    assert broken == ["r2"] and [g.robot for g in grants] == ["r3"]
    # The aisle is removed from the plan: its leases end, waiting requests forget it.
    b.request("r4", ["aisle", "door"], 3.0)
    grants = b.set_zones([DOOR, PASS])
    assert [g.robot for g in grants] == ["r4"] and b.held("r4") == ["door"]
    assert b.table()[0] == {"zone": "door", "capacity": 1, "holders": ["r4"], "waiting": []}


def test_robots_standing_in_each_others_zone_are_found_waiting_for_each_other() -> None:
    b = book()
    assert mine(b.request("r1", ["aisle"], 0.0), "r1")
    assert mine(b.request("r2", ["door"], 0.0), "r2")
    b.leg_over("r1", 3.0, 0.4)  # r1 stopped inside the aisle
    b.leg_over("r2", 8.5, 0.5)  # r2 inside the doorway
    assert not mine(b.request("r1", ["aisle", "door"], 1.0), "r1")
    assert not mine(b.request("r2", ["door", "aisle"], 1.0), "r2")
    assert b.cycles() == [["r1", "r2"]]
    # Staff move r2 out of the doorway by hand and break its lease: r1 goes.
    _, grants = b.break_lease("door", "r2")
    assert [g.robot for g in grants] == ["r1"]


def test_a_robot_standing_in_a_zone_is_not_held_back_by_a_robot_waiting_for_it() -> None:
    b = book()
    assert mine(b.request("r1", ["aisle"], 0.0), "r1")
    b.leg_over("r1", 3.0, 0.4)  # r1 stopped inside the aisle (a table's spot there)
    assert not mine(b.request("r2", ["aisle"], 1.0), "r2")  # r2 waits for r1 to leave
    # r1's next leg goes out through the aisle and the door: it must not wait behind r2,
    # who waits for r1 to leave.
    assert mine(b.request("r1", ["aisle", "door"], 2.0), "r1")
    assert b.cycles() == []
    grants = b.moved("r1", 8.5, 0.5)  # out of the aisle, into the doorway
    assert [g.robot for g in grants] == ["r2"]
