"""Order logs: strict CSV reading (line numbers, all-or-nothing) and the service generator."""

from __future__ import annotations

import collections
import itertools
from pathlib import Path

import pytest

from serveur.cli import main
from serveur.replay.orders import (
    LogOrder,
    OrderLogError,
    demo_tables,
    format_orders,
    generate_orders,
    parse_orders,
    read_orders,
)

TABLES = set(demo_tables())


def test_demo_tables_in_natural_order() -> None:
    assert demo_tables() == [f"T{i}" for i in range(1, 17)]


def test_parse_sorts_by_ready_time_and_keeps_line_numbers() -> None:
    text = "ready_at,table,dish\n30,T2,Laksa\n\n5.5, T1 ,Satay\n30,T3,Kopi\n"
    orders = parse_orders(text, tables=TABLES)
    assert orders == [
        LogOrder(5.5, "T1", "Satay", 4),
        LogOrder(30.0, "T2", "Laksa", 2),
        LogOrder(30.0, "T3", "Kopi", 5),
    ]


def test_every_bad_row_is_reported_with_its_line_and_nothing_is_loaded() -> None:
    text = (
        "ready_at,table,dish\n"
        "10,T1,Laksa\n"  # 2 fine
        "soon,T1,Laksa\n"  # 3 not a number
        "-4,T2,Satay\n"  # 4 negative
        "12,T99,Pho\n"  # 5 not a table of the map
        "13,T3,\n"  # 6 empty dish
        "14,T3\n"  # 7 missing field
        "15,T3,Kopi,extra\n"  # 8 extra field
        "nan,T4,Teh\n"  # 9 not finite
        "16,T4,Te\x01h\n"  # 10 control character
        "17,T4," + "x" * 65 + "\n"  # 11 too long
        "18,T5,Roti\n"  # 12 fine
    )
    with pytest.raises(OrderLogError) as err:
        parse_orders(text, tables=TABLES, source="dinner.csv")
    lines = [n for n, _ in err.value.problems]
    assert lines == [3, 4, 5, 6, 7, 8, 9, 10, 11]
    msgs = dict(err.value.problems)
    assert "not a number" in msgs[3] and "T99" in msgs[5] and "dish is empty" in msgs[6]
    assert "dinner.csv" in str(err.value) and "line 11" in str(err.value)


def test_header_and_empty_file() -> None:
    with pytest.raises(OrderLogError) as err:
        parse_orders("time,table,dish\n1,T1,Laksa\n")
    assert err.value.problems[0][0] == 1
    with pytest.raises(OrderLogError):
        parse_orders("")
    assert parse_orders("READY_AT,Table,Dish\n") == []  # a header alone is an empty service


def test_tables_are_only_checked_against_a_map_when_given() -> None:
    assert parse_orders("ready_at,table,dish\n1,Patio 3,Laksa\n")[0].table == "Patio 3"


def test_read_orders_from_a_file_with_a_bom(tmp_path: Path) -> None:
    p = tmp_path / "log.csv"
    p.write_bytes(b"\xef\xbb\xbfready_at,table,dish\r\n1,T1,Laksa\r\n")
    assert read_orders(p, tables=TABLES) == [LogOrder(1.0, "T1", "Laksa", 2)]
    with pytest.raises(OrderLogError):
        read_orders(tmp_path / "missing.csv")


def test_generator_is_deterministic_per_seed_and_round_trips() -> None:
    tables = demo_tables()[:10]
    a = generate_orders(tables, 2.0, 150, seed=7)
    assert a == generate_orders(tables, 2.0, 150, seed=7)
    assert a != generate_orders(tables, 2.0, 150, seed=8)
    back = parse_orders(format_orders(a), tables=set(tables))
    assert [(o.ready_at, o.table, o.dish) for o in back] == [
        (o.ready_at, o.table, o.dish) for o in a
    ]


def test_generated_service_shape() -> None:
    tables = demo_tables()
    hours, rate = 4.0, 120.0
    runs = [generate_orders(tables, hours, rate, seed=s) for s in range(8)]
    for orders in runs:
        assert all(0 <= o.ready_at < hours * 3600 and o.table in tables for o in orders)
        assert [o.ready_at for o in orders] == sorted(o.ready_at for o in orders)
    # R is the mean number of dishes an hour (over seeds, within 10 %).
    mean = sum(len(o) for o in runs) / len(runs)
    assert abs(mean - rate * hours) < 0.1 * rate * hours
    # Lunch and dinner peaks: the hours around 1/4 and 3/4 of the service are the busiest.
    per_half_hour = collections.Counter(int(o.ready_at // 1800) for r in runs for o in r)
    peaks = per_half_hour[1] + per_half_hour[2] + per_half_hour[5] + per_half_hour[6]
    quiet = per_half_hour[0] + per_half_hour[3] + per_half_hour[4] + per_half_hour[7]
    assert peaks > 1.5 * quiet
    # Parties: dishes for one table come out together (within the kitchen's spread).
    batches = [
        len(list(g))
        for _, g in itertools.groupby(runs[0], key=lambda o: (o.table, o.ready_at // 600))
    ]
    assert sum(batches) / len(batches) > 2.0


def test_generator_rejects_nonsense() -> None:
    with pytest.raises(ValueError):
        generate_orders([], 1.0, 10.0)
    with pytest.raises(ValueError):
        generate_orders(["T1"], 0.0, 10.0)


def test_orders_command(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["orders", "--tables", "4", "--hours", "1", "--rate", "60", "--seed", "3"]) == 0
    out = capsys.readouterr().out
    orders = parse_orders(out, tables=TABLES)
    assert orders and {o.table for o in orders} <= {"T1", "T2", "T3", "T4"}
    assert main(["orders", "--tables", "99"]) == 2
    assert "--tables" in capsys.readouterr().err
