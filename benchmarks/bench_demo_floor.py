"""The demo's campaign against its physical floor, measured in one run.

The campaign of ``bench demo`` (ISO 9283 pose accuracy on the simulated pkm5, 5 poses x 30 cycles x 3 velocities,
speed factor 10,000) cannot finish faster than

    floor = simulated motion / speed factor + dwells / speed factor + round trips x one round-trip time

where the motion is each ``MOVE``'s longest axis travel / its speed (the simulator's rule: all axes arrive
together), the dwells are the protocol's settle times, the round trips are every command the driver exchanges
with the simulator (counted during the run), and one round-trip time is the median of 200 ``ID`` exchanges on the
same pty before the run. Printed: the floor's parts, then min / median / max of the campaign's wall time over
``--repeat`` runs (default 5, a fresh simulator each, started as ``bench demo`` starts it: serving once its
compiled kernel is loaded) and the ratio of the median to the floor.
Target (issue 17): within 1.5x of the floor.

    python benchmarks/bench_demo_floor.py [--repeat 5] [--cycles 30] [--speed-factor 10000]
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

from _timing import load_line

from bench.launch import CAMPAIGN_KERNEL_WAIT_S, simulated_rig_in
from bench.protocols import Runner, summarize
from bench.protocols.iso9283 import PoseAccuracy
from bench.store import Store


def round_trip_s(controller, count: int = 200) -> float:
    """Median wall time of one ``ID`` command and its reply on the controller's link."""
    times = []
    for _ in range(count):
        start = time.perf_counter()
        controller._exchange("ID")
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def run_once(cycles: int, speed_factor: float, seed: int, folder: Path) -> dict[str, float]:
    """One campaign in a fresh store and simulator: its wall time and the parts of its floor."""
    protocol = PoseAccuracy(source="bench demo", cycles=cycles)
    with Store(folder / "bench.db") as store:
        rig = simulated_rig_in(
            store, "pkm5", seed=seed, speed_factor=speed_factor, kernel_wait_s=CAMPAIGN_KERNEL_WAIT_S
        )  # as bench demo starts it
        controller = rig.robot.controller
        try:
            rtt_s = round_trip_s(controller)
            counted = {"exchanges": 0, "motion_s": 0.0, "at": controller.position().steps}
            await_reply, move = controller._await, controller._move

            def counting_await(tag, verb, kinds, timeout_s, **options):
                counted["exchanges"] += "OK" in kinds  # a command's first reply; a DONE is the motion's end
                return await_reply(tag, verb, kinds, timeout_s, **options)

            def timed_move(targets, speed_steps_s):
                # the simulator's own rule: all axes arrive together, the longest travel at speed_steps_s
                speed = controller.speed_steps_s if speed_steps_s is None else speed_steps_s
                travel = max(abs(t - s) for t, s in zip(targets, counted["at"]))
                counted["motion_s"] += travel / speed / speed_factor
                counted["at"] = move(targets, speed_steps_s)
                return counted["at"]

            controller._await, controller._move = counting_await, timed_move
            runner = Runner(rig, store, progress=False)
            start = time.perf_counter()
            result = runner.run(protocol, campaign="floor")
            wall_s = time.perf_counter() - start
        finally:
            rig.close()
    if result.exit_status != "completed":
        raise SystemExit(f"campaign {result.exit_status}: {result.reason}")
    dwell_s = summarize(protocol).settle_s / speed_factor
    return {
        "wall_s": wall_s,
        "motion_s": counted["motion_s"],
        "dwell_s": dwell_s,
        "exchanges": counted["exchanges"],
        "rtt_s": rtt_s,
        "floor_s": counted["motion_s"] + dwell_s + counted["exchanges"] * rtt_s,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--cycles", type=int, default=30)
    parser.add_argument("--speed-factor", type=float, default=10000.0)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    started = os.getloadavg()
    runs = []
    for _i in range(args.repeat):
        with tempfile.TemporaryDirectory() as folder:
            runs.append(run_once(args.cycles, args.speed_factor, args.seed, Path(folder)))
    first = runs[0]
    floor = statistics.median(r["floor_s"] for r in runs)
    walls = [r["wall_s"] for r in runs]
    print(f"campaign: {args.cycles} cycles x 5 poses x 3 velocities, speed factor {args.speed_factor:g}")
    print(f"  simulated motion / speed factor {first['motion_s']:8.3f} s")
    print(f"  dwells / speed factor           {first['dwell_s']:8.3f} s")
    print(
        f"  round trips {first['exchanges']:5d} x {1e3 * first['rtt_s']:.3f} ms  "
        f"{first['exchanges'] * first['rtt_s']:8.3f} s"
    )
    print(f"  physical floor (median of {len(runs)})    {floor:8.3f} s")
    print(
        f"measured wall time, {len(runs)} runs: min {min(walls):.3f} s, median {statistics.median(walls):.3f} s, "
        f"max {max(walls):.3f} s; median / floor = {statistics.median(walls) / floor:.2f}x, min / floor = "
        f"{min(walls) / floor:.2f}x (target <= 1.5x)"
    )
    print(load_line(started))


if __name__ == "__main__":
    main()
