"""The end-to-end order replays of tests/test_e2e.py, on MariaDB instead of a SQLite file.

Same scenarios, same assertions (the test bodies are test_e2e's own functions): one order
delivered, a batch trip in planned order, stop + cancel handing the dishes back, and a server
restarted twice mid-service resuming from what the database holds. Each test gets a fresh
database on the session's private MariaDB server (tests/mariadb_server.py).
"""

from __future__ import annotations

from collections.abc import AsyncIterator
from pathlib import Path

import pytest

from tests import test_e2e as e2e
from tests.conftest import Restaurant, restaurant

pytestmark = pytest.mark.timeout(60)


@pytest.fixture
async def one_robot_mariadb(tmp_path: Path, mariadb_url: str) -> AsyncIterator[Restaurant]:
    async with restaurant(tmp_path, robots=1, db_url=mariadb_url) as r:
        yield r


async def test_one_order_delivered(one_robot_mariadb: Restaurant) -> None:
    assert str(one_robot_mariadb.db).startswith("mariadb://")
    await e2e.test_one_order_delivered(one_robot_mariadb)


async def test_batch_trip_visits_tables_by_distance(one_robot_mariadb: Restaurant) -> None:
    await e2e.test_batch_trip_visits_tables_by_distance(one_robot_mariadb)


async def test_stop_and_cancel_returns_orders(one_robot_mariadb: Restaurant) -> None:
    await e2e.test_stop_and_cancel_returns_orders(one_robot_mariadb)


async def test_restart_mid_service_finishes_the_service(one_robot_mariadb: Restaurant) -> None:
    await e2e.test_restart_mid_service_finishes_the_service(one_robot_mariadb)


async def test_create_is_idempotent_with_keys(one_robot_mariadb: Restaurant) -> None:
    await e2e.test_create_is_idempotent_with_keys(one_robot_mariadb)
