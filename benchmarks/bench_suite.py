"""The whole test suite's wall time (``./dev test -q``) against its 2-core floor, with the machine's speed beside it.

    python benchmarks/bench_suite.py [--repeat 1]                      # this checkout
    git worktree add ../before HEAD~5 && python benchmarks/bench_suite.py --baseline ../before --repeat 3

floor = the CPU the whole machine spent during the run (user + system of every process, from /proc/stat) / the
number of CPUs: the wall time if every core were busy for the whole run. wall / floor says how much of the run
waits (ptys, emulated MCUs kept at real time, child processes, sleeps) rather than computes. The CPU is read
machine-wide because the suite's processes are not all children of one process (its simulators are forked by a
zygote that outlives its worker's accounting).

The development machine is a shared VM whose speed drifts over minutes (a fixed pure-Python loop, printed as
``speed ref`` before and after each run, took 0.85-1.57 s within one hour, idle): compare runs of one session, taking
turns with ``--baseline``, not figures of different days. Each run is the README's test command in that checkout,
with this checkout's virtual environment; ``PYTHONPATH`` points at the checkout, so its own ``bench`` is imported.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent.parent


def speed_reference_s() -> float:
    """Seconds of a fixed pure-Python loop (10^7 additions) in a fresh interpreter: the machine's speed now."""
    code = "import time\nt = time.perf_counter(); s = 0\nfor i in range(10**7): s += i\nprint(time.perf_counter() - t)"
    return float(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout)


def _busy_ticks() -> tuple[int, int]:
    """(busy, steal) clock ticks of all CPUs since boot: user + nice + system + irq + softirq, and steal."""
    with open("/proc/stat") as stat:
        fields = [int(v) for v in stat.readline().split()[1:9]]
    user, nice, system, _idle, _iowait, irq, softirq, steal = fields
    return user + nice + system + irq + softirq, steal


def run_suite(checkout: Path, log: Path) -> dict:
    """``./dev test -q`` in ``checkout``; its wall time, the machine's busy CPU meanwhile and the test counts."""
    env = dict(os.environ, BENCH_VENV=str(Path(sys.prefix)), PYTHONPATH=str(checkout))
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    hz = os.sysconf("SC_CLK_TCK")
    before_s = speed_reference_s()
    busy0, steal0 = _busy_ticks()
    started = time.monotonic()
    with open(log, "w") as out:
        code = subprocess.run(
            ["./dev", "test", "-q"],
            cwd=checkout,
            env=env,
            stdout=out,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
        ).returncode
    wall_s = time.monotonic() - started
    busy1, steal1 = _busy_ticks()
    summary = log.read_text().strip().splitlines()[-1]
    return {
        "code": code,
        "wall_s": wall_s,
        "busy_s": (busy1 - busy0) / hz,
        "steal_s": (steal1 - steal0) / hz,
        "speed_s": (before_s + speed_reference_s()) / 2,
        "summary": summary,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=1, help="runs of each checkout (taking turns)")
    parser.add_argument(
        "--baseline",
        type=Path,
        default=None,
        metavar="CHECKOUT",
        help="another checkout (e.g. a git worktree of an older commit) to take turns with",
    )
    parser.add_argument("--logs", type=Path, default=Path("suite-logs"), help="folder of the runs' pytest output")
    args = parser.parse_args()
    args.logs.mkdir(parents=True, exist_ok=True)
    checkouts = {"this": HERE} if args.baseline is None else {"before": args.baseline.resolve(), "after": HERE}
    for checkout in checkouts.values():  # ./dev would install another pyproject.toml into this environment
        if (checkout / "pyproject.toml").read_bytes() != (HERE / "pyproject.toml").read_bytes():
            sys.exit(
                f"bench_suite: --baseline {checkout}: its pyproject.toml differs from this checkout's, "
                "expected the same dependencies (give the baseline a virtual environment of its own)"
            )
    cpus = os.cpu_count()
    runs: dict[str, list[dict]] = {name: [] for name in checkouts}
    for i in range(args.repeat):
        for name, checkout in checkouts.items():
            run = run_suite(checkout, args.logs / f"{name}-{i + 1}.log")
            runs[name].append(run)
            print(
                f"{name:6s} run {i + 1}: wall {run['wall_s']:6.1f} s, machine CPU {run['busy_s']:6.1f} s (steal "
                f"{run['steal_s']:.1f} s), floor {run['busy_s'] / cpus:6.1f} s, wall / floor "
                f"{run['wall_s'] * cpus / run['busy_s']:.2f}, speed ref {run['speed_s']:.2f} s, exit {run['code']}: "
                f"{run['summary']}",
                flush=True,
            )
    for name, done in runs.items():
        walls = [r["wall_s"] for r in done]
        busy = [r["busy_s"] for r in done]
        print(
            f"{name:6s} wall min {min(walls):.1f} median {float(np.median(walls)):.1f} max {max(walls):.1f} s; "
            f"machine CPU min {min(busy):.1f} median {float(np.median(busy)):.1f} max {max(busy):.1f} s; "
            f"target 180 s wall on {cpus} CPUs"
        )
    if args.baseline is not None:
        ratio = float(
            np.median([r["wall_s"] for r in runs["before"]]) / np.median([r["wall_s"] for r in runs["after"]])
        )
        cpu = float(np.median([r["busy_s"] for r in runs["before"]]) / np.median([r["busy_s"] for r in runs["after"]]))
        print(f"before / after, medians: wall {ratio:.2f}x, machine CPU {cpu:.2f}x")


if __name__ == "__main__":
    main()
