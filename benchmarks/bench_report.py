"""Timing of ``bench report`` on a demo-sized pose run (5 poses x 30 cycles x 3 velocities, 450 samples) and on a long
path run (about 2.3 million streamed points in its raw CSV).

Stages, each timed ``--repeat`` times (min / median / max, wall and CPU): collect (store -> numbers), document
(figures built and laid out once), HTML (each figure drawn once, as PNG), PDF (the same images, reused), and the
whole ``write_report`` call (target 2 s, issue 17). Then ``bench report RUN`` as a whole process (import, store
read, compute, write; target 3 s, issue 18) against its floor, a process that only imports matplotlib and pandas;
``--path`` adds the long path run (simulated once, its cycles copied in the store to the size of a long run).
Every line prints the machine's load.

    python benchmarks/bench_report.py                         # a synthetic run like the demo's
    python benchmarks/bench_report.py --path                  # and a long path run's report
    python benchmarks/bench_report.py --store demo-out/bench.db --run 1   # a stored run (e.g. ``bench demo``'s)
    git worktree add ../before HEAD~3 && python benchmarks/bench_report.py --baseline ../before   # before/after
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.reports import collect, write_report
from bench.reports.html import render_html
from bench.reports.pdf import render_pdf
from bench.reports.pose_document import run_document
from bench.store import Store

#: write_report of the demo run (issue 17) and ``bench report`` of it as a whole process (issue 18), seconds.
TARGET_S = 2.0
PROCESS_TARGET_S = 3.0
CUBE = {
    "P1": (110.0, 0.0, 320.0),
    "P2": (94.0, -16.0, 304.0),
    "P3": (94.0, 16.0, 304.0),
    "P4": (126.0, 16.0, 336.0),
    "P5": (126.0, -16.0, 336.0),
}
SETTINGS = {
    "robot": {"driver": "Pkm5Controller", "firmware": {"firmware_version": "1.0.0-sim"}, "rated_speed_steps_s": 200},
    "instrument": {"instrument": "two simulated optical mice (x-y, x-z)", "cpi": 800.0, "noise_counts": 0.05},
    "simulator": {"seed": 0},
}


def demo_like_run(store: Store) -> int:
    """A completed pose run of the demo's size (the simulator's run takes 15-20 s; the report reads only this)."""
    config = {
        "protocol": "iso9283_pose",
        "protocol_version": "1",
        "robot": "pkm5",
        "cycles": 30,
        "velocities_pct": [100.0, 50.0, 10.0],
        "loads_kg": [0.0],
        "cube_centre_mm": [110.0, 0.0, 320.0],
        "cube_side_mm": 40.0,
        "plane": "x=z",
        "poses": None,
        "settle_s": 1.0,
    }
    rng = np.random.default_rng(0)
    run_id = store.start_run(
        protocol_name="iso9283_pose", protocol_version="1", robot="pkm5", config=config, settings=SETTINGS
    )
    step = 0
    for velocity in config["velocities_pct"]:
        for cycle in range(1, 31):
            for pose in ("P1", "P5", "P4", "P3", "P2"):
                command = np.array(CUBE[pose])
                attained = command + (1.0, 1.4, -0.7) + rng.normal(0.0, 0.4, 3)
                values = dict(zip(("x_mm", "y_mm", "z_mm", "cmd_x_mm", "cmd_y_mm", "cmd_z_mm"), (*attained, *command)))
                store.add_sample(
                    run_id,
                    step,
                    values={**{k: float(v) for k, v in values.items()}, "velocity_pct": velocity, "load_kg": 0.0},
                    pose=pose,
                    cycle=cycle,
                    t_s=1.5 * step,
                )
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
    return (
        f"{name:<14} wall min {min(walls):6.2f}  median {statistics.median(walls):6.2f}  max {max(walls):6.2f} s"
        f"   CPU median {statistics.median(cpus):6.2f} s"
    )


def _load() -> str:
    return "load average {:.2f}, {:.2f}, {:.2f}".format(*os.getloadavg())


HERE = Path(__file__).resolve().parents[1]


def _environment(checkout: Path) -> dict[str, str]:
    """This process's environment with ``checkout``'s bench first on the path."""
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(checkout), os.environ.get("PYTHONPATH", "")])}


def _process(arguments: list[str], checkout: Path = HERE) -> tuple[float, float, str]:
    """Wall and CPU seconds (user + system, the child's) of one ``python ARGUMENTS``, and its stdout."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, *arguments],
        check=True,
        env=_environment(checkout),
        cwd=checkout,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime, done.stdout


def _process_times(arguments: list[str], repeat: int) -> list[float]:
    """Wall seconds of ``repeat`` runs of ``python ARGUMENTS`` (this worktree's bench first on the path)."""
    return [_process(arguments)[0] for _ in range(repeat)]


def _spread(walls: list[float]) -> str:
    return f"min {min(walls):6.2f}  median {statistics.median(walls):6.2f}  max {max(walls):6.2f} s"


#: What a report process imports of other packages (the part of its time no change to bench can remove): pandas for
#: the analysis, matplotlib's Figure (with mplot3d, which matplotlib.projections imports), reportlab and jinja2.
LIBRARIES = "import numpy, pandas, matplotlib.figure, reportlab.platypus, jinja2"


def _report_argv(store_path: Path, run_id: int, out: Path) -> list[str]:
    """A child interpreter's arguments for ``bench report RUN`` through the installed entry point's ``main``."""
    return [
        "-c",
        "import sys; from bench.cli import main; sys.exit(main())",
        "report",
        str(run_id),
        "--store",
        str(store_path),
        "--out",
        str(out),
        "--quiet",
    ]


def whole_process(store_path: Path, run_id: int, out: Path, repeat: int) -> None:
    """``bench report RUN`` as a user runs it, against a process that imports only matplotlib and pandas."""
    floor = _process_times(["-c", "import matplotlib, pandas"], repeat)
    libraries = _process_times(["-c", LIBRARIES], repeat)
    report = _process_times(_report_argv(store_path, run_id, out), repeat)
    print(f"{'floor (import matplotlib, pandas)':<36} wall {_spread(floor)}   {_load()}")
    print(f"{'the libraries a report imports':<36} wall {_spread(libraries)}   {_load()}")
    print(f"{'bench report RUN (whole process)':<36} wall {_spread(report)}   {_load()}")
    median = statistics.median(report)
    print(
        f"bench report RUN: median {median:.2f} s = {median / statistics.median(floor):.1f} x the import floor, "
        f"{median / PROCESS_TARGET_S:.2f} x the {PROCESS_TARGET_S:g} s target"
    )


#: Run in a child process of either checkout: ``write_report`` of the run once (after the imports, the first call in
#: the process), as JSON wall and CPU seconds.
_IN_PROCESS = """
import json, sys, time
from pathlib import Path
from bench.reports import write_report
store, run_id, out = sys.argv[1], int(sys.argv[2]), Path(sys.argv[3])
wall, cpu = time.perf_counter(), time.process_time()
write_report(store, run_id, out)
print(json.dumps([time.perf_counter() - wall, time.process_time() - cpu]))
"""


def against_baseline(baseline: Path, store_path: Path, run_id: int, out: Path, repeat: int) -> None:
    """Before/after in one run: ``write_report`` (in a child process of each checkout, after its imports) and
    ``bench report RUN`` as a whole process, the two checkouts taking turns so both see the same load."""
    checkouts = {"before": baseline.resolve(), "after": HERE}
    inside = {name: ([], []) for name in checkouts}
    whole = {name: ([], []) for name in checkouts}
    for index in range(repeat):
        for name, checkout in checkouts.items():
            _, _, said = _process(
                ["-c", _IN_PROCESS, str(store_path), str(run_id), str(out / name / f"in{index}")], checkout
            )
            wall, cpu = json.loads(said)
            inside[name][0].append(wall)
            inside[name][1].append(cpu)
            wall, cpu, _ = _process(_report_argv(store_path, run_id, out / name / f"p{index}"), checkout)
            whole[name][0].append(wall)
            whole[name][1].append(cpu)
    print(f"before = {checkouts['before']}, after = {checkouts['after']}, taking turns, {repeat} each   {_load()}")
    for label, measured in (("write_report (1st call)", inside), ("bench report RUN", whole)):
        for name in checkouts:
            walls, cpus = measured[name]
            print(f"{label + ' ' + name:<28} wall {_spread(walls)}   CPU {_spread(cpus)}")
        ratio = statistics.median(measured["before"][0]) / statistics.median(measured["after"][0])
        cpu_ratio = statistics.median(measured["before"][1]) / statistics.median(measured["after"][1])
        print(f"{label}: before / after = {ratio:.2f} x wall (medians), {cpu_ratio:.2f} x CPU")


def long_path_run(folder: Path, points: int) -> tuple[Path, int]:
    """A completed path run with about ``points`` streamed points: a short simulated ``iso9283_path`` run (both
    shapes, 2 cycles, seeded), its path samples copied with new cycle numbers until the run holds ``points`` (one
    SQL statement per copy: the store commits sample by sample, minutes for 14,000 samples)."""
    from bench.protocols import Runner
    from bench.protocols.path import PathAccuracy
    from bench.simulators.rig import simulated_rig

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from reports_runs import copy_path_cycles

    path = folder / "path.db"
    with Store(path) as store:
        rig = simulated_rig("pkm5", seed=6, speed_factor=10000)
        try:
            run_id = (
                Runner(rig, store)
                .run(PathAccuracy(shape="both", cycles=2, velocities_pct=[100.0], final_hold_s=0.2))
                .run_id
            )
        finally:
            rig.close()
        per_copy = sum(len(s.raw["series"]["t_s"]) for s in store.samples(run_id, kind="path"))
    copy_path_cycles(path, run_id, max(1, round(points / per_copy)) - 1)
    return path, run_id


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--store", type=Path, default=None, help="a stored run to report instead of the synthetic one")
    parser.add_argument("--run", type=int, default=1)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--path", action="store_true", help="also a long path run's report (simulates one, ~1 min)")
    parser.add_argument("--path-points", type=int, default=2_300_000)
    parser.add_argument(
        "--baseline",
        type=Path,
        default=None,
        metavar="CHECKOUT",
        help="another checkout of bench (e.g. a git worktree of the previous commit): before/after "
        "ratios of write_report and bench report RUN, the two taking turns",
    )
    args = parser.parse_args()
    print(_load())
    if sys.flags.dont_write_bytecode:  # PYTHONDONTWRITEBYTECODE: no .pyc is written, each child compiles bench
        print(
            "note: bytecode is not written here; without `python -m compileall bench motion` (in each checkout) "
            "every child process compiles bench from source (about 0.5 s)"
        )
    with tempfile.TemporaryDirectory() as folder:
        store = Store(args.store) if args.store else Store(Path(folder) / "bench.db")
        run_id = args.run if args.store else demo_like_run(store)
        walls, cpus, report = _timed(lambda: collect(store, run_id), args.repeat)
        print(_line("collect", walls, cpus))
        stages = {"document": ([], []), "html": ([], []), "pdf": ([], [])}
        for _ in range(args.repeat):  # a fresh document each time: its figures are drawn once, by the first format
            walls, cpus, document = _timed(lambda: run_document(report, []), 1)
            timed = {
                "document": (walls, cpus),
                "html": _timed(lambda: render_html(document), 1)[:2],
                "pdf": _timed(lambda: render_pdf(document), 1)[:2],
            }
            for name, (walls, cpus) in timed.items():
                stages[name][0].extend(walls)
                stages[name][1].extend(cpus)
        for name, (walls, cpus) in stages.items():
            print(_line(name, walls, cpus))
        walls, cpus, _ = _timed(lambda: write_report(store, run_id, Path(folder) / "out"), args.repeat)
        print(_line("write_report", walls, cpus) + f"   {_load()}")
        store.close()
        median = statistics.median(walls)
        print(
            f"demo-sized write_report: median {median:.2f} s wall, {statistics.median(cpus):.2f} s CPU = "
            f"{median / TARGET_S:.2f} x the {TARGET_S:g} s target"
        )
        whole_process(args.store or Path(folder) / "bench.db", run_id, Path(folder) / "process", args.repeat)
        if args.baseline is not None:
            against_baseline(
                args.baseline, args.store or Path(folder) / "bench.db", run_id, Path(folder) / "ab", args.repeat
            )
        if args.path:
            path, path_run = long_path_run(Path(folder), args.path_points)
            walls, cpus, paths = _timed(
                lambda: write_report(path, path_run, Path(folder) / "path-out"), max(1, args.repeat // 2)
            )
            rows = sum(1 for _ in paths.csv[0].open("rb")) - 1
            size = paths.csv[0].stat().st_size / 2**20
            print(_line("path report", walls, cpus) + f"   {rows:,} rows in its CSV ({size:.0f} MiB)   {_load()}")
            floor = _timed(lambda: shutil.copyfile(paths.csv[0], Path(folder) / "copy.csv"), 3)[0]
            print(
                f"long path run report: median {statistics.median(walls):.1f} s wall; copying its CSV alone "
                f"{min(floor):.2f} s"
            )


if __name__ == "__main__":
    main()
