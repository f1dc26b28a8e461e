"""Run tests again and again under CPU load, to show that they are not flaky (the project's rule: a test must pass
20 times in a row under CPU load).

The load is ``--burners`` processes spinning on the CPU (default: one per core, as ``stress -c N`` does), started
before the first run and stopped after the last. The tests run ``--times`` times in a row in fresh pytest
processes; the script stops at the first failing run and exits 1, naming it. Example::

    python tools/repeat_under_load.py --times 20 tests/test_gui_safety.py tests/test_gui_app.py
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import subprocess
import sys
import time


def _spin() -> None:
    while True:
        pass


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--times", type=int, default=20, help="runs in a row (default 20)")
    parser.add_argument(
        "--burners",
        type=int,
        default=os.cpu_count() or 2,
        help="CPU-spinning processes beside the tests (default: one per core)",
    )
    parser.add_argument("pytest_args", nargs="+", help="test paths and pytest options (e.g. -k, -x)")
    args, extra = parser.parse_known_args(argv)
    args.pytest_args += extra
    burners = [multiprocessing.Process(target=_spin, daemon=True) for _ in range(args.burners)]
    for burner in burners:
        burner.start()
    durations = []
    try:
        for attempt in range(1, args.times + 1):
            started = time.monotonic()
            done = subprocess.run(
                [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *args.pytest_args],
                capture_output=True,
                text=True,
                check=False,
            )
            durations.append(time.monotonic() - started)
            last = (done.stdout.strip().splitlines() or ["(no output)"])[-1]
            print(f"run {attempt}/{args.times}: {last} ({durations[-1]:.0f} s)", flush=True)
            if done.returncode != 0:
                print(done.stdout[-6000:], done.stderr[-2000:], sep="\n", file=sys.stderr)
                print(f"failed on run {attempt} of {args.times} under {args.burners} CPU burners", file=sys.stderr)
                return 1
    finally:
        for burner in burners:
            burner.terminate()
    durations.sort()
    print(
        f"{args.times} runs in a row passed under {args.burners} CPU burners; run time min {durations[0]:.0f} s, "
        f"median {durations[len(durations) // 2]:.0f} s, max {durations[-1]:.0f} s"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
