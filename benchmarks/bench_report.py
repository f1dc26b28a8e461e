"""Timing of ``bench report`` on a demo-sized pose run: 5 poses x 30 cycles x 3 velocities (450 samples).

Stages, each timed ``--repeat`` times (min / median / max, wall and CPU): collect (store -> numbers), document
(figures built and laid out once), HTML (each figure drawn once, as PNG), PDF (the same images, reused), and the
whole ``write_report`` call. Target: the demo report under 3 s (issue 18); the ratio to the target is printed.

    python benchmarks/bench_report.py                         # a synthetic run like the demo's
    python benchmarks/bench_report.py --store demo-out/bench.db --run 1   # a stored run (e.g. ``bench demo``'s)
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.reports import collect, write_report
from bench.reports.document import run_document
from bench.reports.html import render_html
from bench.reports.pdf import render_pdf
from bench.store import Store

TARGET_S = 3.0
CUBE = {"P1": (110.0, 0.0, 320.0), "P2": (94.0, -16.0, 304.0), "P3": (94.0, 16.0, 304.0),
        "P4": (126.0, 16.0, 336.0), "P5": (126.0, -16.0, 336.0)}
SETTINGS = {"robot": {"driver": "Pkm5Controller", "firmware": {"firmware_version": "1.0.0-sim"},
                      "rated_speed_steps_s": 200},
            "instrument": {"instrument": "two simulated optical mice (x-y, x-z)", "cpi": 800.0,
                           "noise_counts": 0.05},
            "simulator": {"seed": 0}}


def demo_like_run(store: Store) -> int:
    """A completed pose run of the demo's size (the simulator's run takes 15-20 s; the report reads only this)."""
    config = {"protocol": "iso9283_pose", "protocol_version": "1", "robot": "pkm5", "cycles": 30,
              "velocities_pct": [100.0, 50.0, 10.0], "loads_kg": [0.0], "cube_centre_mm": [110.0, 0.0, 320.0],
              "cube_side_mm": 40.0, "plane": "x=z", "poses": None, "settle_s": 1.0}
    rng = np.random.default_rng(0)
    run_id = store.start_run(protocol_name="iso9283_pose", protocol_version="1", robot="pkm5", config=config,
                             settings=SETTINGS)
    step = 0
    for velocity in config["velocities_pct"]:
        for cycle in range(1, 31):
            for pose in ("P1", "P5", "P4", "P3", "P2"):
                command = np.array(CUBE[pose])
                attained = command + (1.0, 1.4, -0.7) + rng.normal(0.0, 0.4, 3)
                values = dict(zip(("x_mm", "y_mm", "z_mm", "cmd_x_mm", "cmd_y_mm", "cmd_z_mm"),
                                  (*attained, *command)))
                store.add_sample(run_id, step, values={**{k: float(v) for k, v in values.items()},
                                                       "velocity_pct": velocity, "load_kg": 0.0},
                                 pose=pose, cycle=cycle, t_s=1.5 * step)
                step += 1
    store.set_status(run_id, "completed")
    return run_id


def _timed(function, repeat: int):
    walls, cpus, result = [], [], None
    for _ in range(repeat):
        wall, cpu = time.perf_counter(), time.process_time()
        result = function()
        walls.append(time.perf_counter() - wall)
        cpus.append(time.process_time() - cpu)
    return walls, cpus, result


def _line(name: str, walls: list[float], cpus: list[float]) -> str:
    return (f"{name:<14} wall min {min(walls):6.2f}  median {statistics.median(walls):6.2f}  max {max(walls):6.2f} s"
            f"   CPU median {statistics.median(cpus):6.2f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--store", type=Path, default=None, help="a stored run to report instead of the synthetic one")
    parser.add_argument("--run", type=int, default=1)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        store = Store(args.store) if args.store else Store(Path(folder) / "bench.db")
        run_id = args.run if args.store else demo_like_run(store)
        walls, cpus, report = _timed(lambda: collect(store, run_id), args.repeat)
        print(_line("collect", walls, cpus))
        stages = {"document": ([], []), "html": ([], []), "pdf": ([], [])}
        for _ in range(args.repeat):  # a fresh document each time: its figures are drawn once, by the first format
            walls, cpus, document = _timed(lambda: run_document(report, []), 1)
            timed = {"document": (walls, cpus), "html": _timed(lambda: render_html(document), 1)[:2],
                     "pdf": _timed(lambda: render_pdf(document), 1)[:2]}
            for name, (walls, cpus) in timed.items():
                stages[name][0].extend(walls)
                stages[name][1].extend(cpus)
        for name, (walls, cpus) in stages.items():
            print(_line(name, walls, cpus))
        walls, cpus, _ = _timed(lambda: write_report(store, run_id, Path(folder) / "out"), args.repeat)
        print(_line("write_report", walls, cpus))
        store.close()
    median = statistics.median(walls)
    print(f"demo-sized report: median {median:.2f} s wall, {statistics.median(cpus):.2f} s CPU = "
          f"{median / TARGET_S:.2f} x the {TARGET_S:g} s target")


if __name__ == "__main__":
    main()
