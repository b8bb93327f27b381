"""A first trip, end to end: one dish from the kitchen pass to a table and the robot home again.

    serveur demo --robots 1 --time-scale 5            # prints: log in as staff / PASSWORD
    python3 examples/first_trip.py --password PASSWORD

Python 3.11 and the `websockets` package only; docs/protocol.md explains every message.
"""

import argparse
import asyncio
import itertools
import json
import os

from websockets.asyncio.client import connect
from websockets.exceptions import WebSocketException

p = argparse.ArgumentParser(description="Send one dish to a table with a serveur robot.")
p.add_argument("--url", default=os.environ.get("SERVEUR_URL", "ws://127.0.0.1:8765/ws"))
p.add_argument("--user", default=os.environ.get("SERVEUR_USER", "staff"))
p.add_argument("--password", default=os.environ.get("SERVEUR_PASSWORD"))
p.add_argument("--robot", default="r1")
p.add_argument("--table", default="T3")
p.add_argument("--dish", default="Laksa")
args = p.parse_args()
if not args.password:
    p.error("give --password or set SERVEUR_PASSWORD (`serveur demo` prints it)")


class Refused(Exception):
    """The server answered a request with an error."""


async def main() -> None:
    ids, robots, tasks = itertools.count(1), {}, {}
    async with connect(args.url) as ws:

        async def read() -> dict:  # the next message; our copy of the robots and trips follows
            msg = json.loads(await ws.recv())
            if msg["servermsg"] == "error":
                raise Refused(f"{msg['code']}: {msg['message']}")
            data = msg.get("data") or {}
            if msg["servermsg"] == "update":
                data = {msg["topic"]: [data]}
            robots.update({r["name"]: r for r in data.get("robots", [])})
            tasks.update({t["id"]: t for t in data.get("tasks", [])})
            return msg

        async def call(verb: str, **fields) -> dict:  # a request; its reply
            await ws.send(json.dumps({"clientmsg": verb, "id": (i := next(ids)), **fields}))
            while (msg := await read()).get("id") != i:
                pass  # an update, applied by read()
            return msg

        async def until(*statuses: str) -> str:  # wait for the robot to be in one of these
            while (status := robots[args.robot]["status"]) not in statuses:
                await read()
            return status

        who = (await call("login", username=args.user, password=args.password))["session"]
        print(f"logged in as {who['user']} ({who['role']})")
        await call("data", topics=["robots", "tasks"])  # a snapshot, then every change
        if args.robot not in robots:
            raise Refused(f"no robot {args.robot!r}; there are {sorted(robots)}")
        while (status := robots[args.robot]["status"]) == "Offline":
            await read()  # its link comes up
        if status == "Ready":
            await call("control", robot=args.robot, action="auto")  # "Start delivering"
        elif status not in ("Awaiting", "Transit"):
            raise Refused(f"{args.robot} is {status}: not free for a trip")
        print(f"{args.robot} is in automatic mode; waiting for it at home (Awaiting)")
        await until("Awaiting")
        order = (await call("create", type="order", dish=args.dish, table=args.table))["order"]
        print(f"order {order['id']}: {args.dish} for {args.table}, ready at the pass")
        trip = (await call("create", type="task", orders=[order["id"]]))["tasks"][0]["id"]
        print(f"trip {trip} made (the cart); waiting for {args.robot} to take it")
        while robots[args.robot]["current_task"] != trip:
            await read()
        await until("Loading")
        print(f"{args.robot} is Loading at the pass; the tray is loaded: pressing Go")
        await call("go", robot=args.robot, task=trip, stop=0)
        print(f"{args.robot} is Delivering to {args.table}")
        await until("Delivered")
        print(f"{args.robot} is at {args.table}: Delivered; the guests take their {args.dish}")
        await call("next", robot=args.robot, task=trip, stop=tasks[trip]["current_stop"])
        print(f"food collected; {args.robot} goes home (Transit)")
        await until("Awaiting")
        served = (await call("order", table=args.table))["orders"]
        status = next(o["status"] for o in served if o["id"] == order["id"])
        print(f"{args.robot} is home, Awaiting orders; order {order['id']} is {status}")


try:
    asyncio.run(asyncio.wait_for(main(), timeout=300))
except (Refused, OSError, WebSocketException, TimeoutError) as exc:  # or stuck for 5 minutes
    raise SystemExit(f"first trip stopped: {type(exc).__name__}: {exc}") from None
