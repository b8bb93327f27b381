"""Protocol fuzzing at volume: ``tests/test_fuzz.py``'s examples, 100,000 of them by default.

One live restaurant on loopback (server on 127.0.0.1, two simulated robots, a SQLite file in a
temporary directory), two fuzz connections, the same hypothesis strategies
(``tests/fuzz_strategies.py``) and the same checks (``tests/fuzz_harness.py``): every frame
answered once with ok or a documented error (never ``internal_error``), connections kept open,
nothing logged as an error, and the database invariants (``tests/invariants.py``) checked every
``--check-every`` examples and at the end, with every robot's lock held.

A failure is counted and printed, and the run goes on (the connections are reopened).
Bounded: stops after ``--examples`` examples or ``--max-minutes`` minutes, whichever first.

Run: ``python bench/fuzz.py`` (about 75 minutes on a 2-core box: some 22 examples, 130
frames a second); ``python bench/fuzz.py --max-minutes 25`` or ``--examples 5000 --seed 7`` for
a shorter one. Waits for robot statuses are 0.3x those of the CI test (``--wait-scale``): volume
over depth; robots keep moving between examples anyway.
"""

from __future__ import annotations

import argparse
import re
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # for ``tests.*``

from hypothesis import HealthCheck, Phase, given, seed, settings

from tests.fuzz_harness import LiveRestaurant
from tests.fuzz_strategies import Step, examples


class _TimeUp(BaseException):
    """Ends the hypothesis run early (a BaseException, so it is not taken for a failure)."""


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--examples", type=int, default=100_000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--time-scale", type=float, default=30.0, help="simulated robots' speed-up")
    ap.add_argument("--wait-scale", type=float, default=0.3, help="multiplies Wait timeouts")
    ap.add_argument("--check-every", type=int, default=50, help="examples between DB checks")
    ap.add_argument("--max-minutes", type=float, default=90.0, help="stop after this long")
    ap.add_argument("--report-every", type=int, default=5000, help="progress line every N")
    args = ap.parse_args()

    started = time.perf_counter()
    deadline = started + args.max_minutes * 60
    kinds: Counter[str] = Counter()

    with tempfile.TemporaryDirectory(prefix="serveur-fuzz-") as tmp:
        live = LiveRestaurant(
            Path(tmp), robots=2, time_scale=args.time_scale, wait_scale=args.wait_scale
        ).start()
        stats = live.stats
        try:

            @seed(args.seed)
            @settings(
                max_examples=args.examples,
                deadline=None,
                database=None,
                phases=(Phase.generate,),  # no shrinking: failures are counted, not minimised
                suppress_health_check=list(HealthCheck),
            )
            @given(examples())
            def one_example(steps: list[Step]) -> None:
                if time.perf_counter() > deadline:
                    raise _TimeUp
                n = stats.examples + 1
                try:
                    live.run(steps, check=n % args.check_every == 0)
                except AssertionError as exc:
                    # Every new kind of failure is printed (the first line, digits masked,
                    # says the kind), and the count of each at the end: a cluster of one
                    # bug's repeats must not hide the next bug.
                    text = str(exc)
                    kind = re.sub(r"\d+", "N", (text.splitlines() or ["?"])[0])
                    kinds[kind] += 1
                    if kinds[kind] == 1:
                        print(f"FAILURE in example {n}: {text[:3000]}", flush=True)
                if n % args.report_every == 0:
                    print(
                        f"  {n} examples, {stats.frames} frames, {len(stats.failures)} failures,"
                        f" {time.perf_counter() - started:.0f} s",
                        flush=True,
                    )

            try:
                one_example()
            except _TimeUp:
                print(f"stopped by --max-minutes {args.max_minutes}", flush=True)
            try:
                live.check()  # the final state, whatever the cadence
            except AssertionError as exc:
                stats.failures.append(str(exc))
                print(f"FAILURE at the end: {exc}", flush=True)
        finally:
            live.close()

    wall = time.perf_counter() - started
    print()
    print(
        f"bench/fuzz: seed {args.seed}, time scale {args.time_scale}, robots 2, connections 2,"
        f" invariants every {args.check_every} examples"
    )
    print(stats.summary())
    for kind, count in kinds.most_common():
        print(f"failure kind x{count}: {kind[:300]}")
    print(
        f"wall {wall:.1f} s ({stats.examples / wall:.1f} examples/s,"
        f" {stats.frames / wall:.0f} frames/s)"
    )
    return 1 if stats.failures else 0


if __name__ == "__main__":
    sys.exit(main())
