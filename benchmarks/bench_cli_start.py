"""Whole-process start time of ``bench`` against ``python -c pass`` (the interpreter's own floor), measured in one run.

Each command runs 5 times in a fresh interpreter (the same ``sys.executable``, so site-packages and the editable
install cost the same on both sides); printed: min / median / max wall time and the ratio of the medians.
Targets (issue 17): ``bench --help`` and ``bench --version`` within 5x of ``python -c pass``; ``bench kin ik`` < 1 s.

    python benchmarks/bench_cli_start.py
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import time

REPEAT = 5
BENCH = [sys.executable, "-m", "bench.cli"]
COMMANDS = {
    "python -c pass": [sys.executable, "-c", "pass"],
    "bench --version": [*BENCH, "--version"],
    "bench --help": [*BENCH, "--help"],
    "bench kin ik pkm5 111.31 -20 310": [*BENCH, "kin", "ik", "pkm5", "111.31", "-20", "310"],
    "bench kin fk pkm5 184 184 184 184 192 192": [
        *BENCH,
        "kin",
        "fk",
        "pkm5",
        "184",
        "184",
        "184",
        "184",
        "192",
        "192",
    ],
}


def wall_times_s(argv: list[str], repeat: int = REPEAT) -> list[float]:
    """Wall time of ``repeat`` runs of ``argv``, each in a new process (stdout and stderr discarded)."""
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
        times.append(time.perf_counter() - start)
    return times


def main() -> None:
    results = {name: wall_times_s(argv) for name, argv in COMMANDS.items()}
    floor = statistics.median(results["python -c pass"])
    print(f"{'command':<44} {'min_s':>7} {'median_s':>8} {'max_s':>7} {'x python -c pass':>17}")
    for name, times in results.items():
        median = statistics.median(times)
        print(f"{name:<44} {min(times):7.3f} {median:8.3f} {max(times):7.3f} {median / floor:17.1f}")


if __name__ == "__main__":
    main()
