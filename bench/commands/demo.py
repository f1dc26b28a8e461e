"""``bench demo``: the main job end to end on a fresh install, in well under a minute.

Starts the simulated pkm5 controller (a separate process on a pseudo-terminal) and the simulated optical mice,
runs a complete ISO 9283 pose campaign (P1-P5 of the largest cube in the workspace, 30 cycles, 100/50/10 %
velocity) with the simulator's speed factor, stores every sample in ``OUT/bench.db``, exports the tidy table,
analyses it with :mod:`bench.metrology`, and writes ``OUT/results.csv`` (per pose, rounded by U, with the simulator's
true attained AP/RP next to the measured ones) and the report of :mod:`bench.reports` (``OUT/report_run<ID>.html``
and ``.pdf``: the one report, rendered from one content model, so no second document can disagree with it).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from bench.errors import ConfigError, InsufficientData

if TYPE_CHECKING:  # imported inside the functions: building the parser stays cheap
    import pandas as pd

    from bench.store import Store

__all__ = ["analyze_run", "register", "rounded_results"]


def register(groups: argparse._SubParsersAction) -> None:
    demo = groups.add_parser(
        "demo",
        help="simulated ISO 9283 pose campaign on the pkm5, analysed, in < 1 min",
        description=__doc__.splitlines()[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    demo.add_argument("--out", default="demo-out", help="folder for the store, the table and the report")
    demo.add_argument("--seed", type=int, default=1, help="seed of the simulated robot's errors and noise")
    demo.add_argument("--cycles", type=int, default=30, help="cycles per pose (ISO: 30)")
    demo.add_argument("--speed-factor", type=float, default=10000.0, help="simulated time speed-up")
    demo.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    demo.set_defaults(handler=_demo)


def analyze_run(store: Store, run_id: int) -> pd.DataFrame:
    """AP/RP per pose and condition of a stored pose run, in report order (P1..P5 per velocity); with the
    simulator's truth when the samples carry it.

    U(AP) carries the instrument's standard uncertainty exactly as the full report does (the run's stored
    instrument settings, :func:`bench.reports.content.counts_instrument`), so results.csv and the HTML/PDF
    give the same U.
    """
    import pandas as pd

    from bench.metrology.formatting import report_order
    from bench.metrology.tables import analyze_poses, pose_result_json, pose_table
    from bench.reports.content import analysis_table, calibrations_in_force
    from bench.reports.instrument import counts_instrument

    table = analysis_table(store, run_id)
    run = store.run(run_id)
    instrument = counts_instrument(
        run, calibrations_in_force(store, run), dims=sum(c in table.columns for c in ("x_mm", "y_mm", "z_mm"))
    )
    rows = []
    measured = report_order(analyze_poses(table, instrument_u_mm=instrument.sigma_mm or 0.0))
    truth = None
    raw = [s.raw or {} for s in store.samples(run_id, kind="pose")]
    if raw and all("true_pose" in r for r in raw):
        true_table = table.copy()
        true_table[["x_mm", "y_mm", "z_mm"]] = [r["true_pose"][:3] for r in raw]
        truth = {r.label: r for r in analyze_poses(pose_table(true_table))}
    for result in measured:
        figures = pose_result_json(result)
        row = {"pose": result.pose, **dict(result.conditions), "n": figures["n"]}
        row.update({k: figures[k] for k in ("AP_mm", "APx_mm", "APy_mm", "APz_mm", "RP_mm", "U_AP_mm", "U_RP_mm")})
        if truth is not None:
            row["true_AP_mm"] = truth[result.label].accuracy.ap_mm
            row["true_RP_mm"] = truth[result.label].repeatability.rp_mm
        rows.append(row)
    return pd.DataFrame(rows)


#: Columns rounded by U(AP) and by U(RP) in the printed results (the rest are conditions and counts).
_BY_U = {"U_AP_mm": ("AP_mm", "APx_mm", "APy_mm", "APz_mm", "true_AP_mm"), "U_RP_mm": ("RP_mm", "true_RP_mm")}


def rounded_results(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` (of :func:`analyze_run`) as text, every value rounded by its row's uncertainty: U to two
    significant digits and the value to the same decimal place (:mod:`bench.metrology.formatting`, the rule of the
    HTML/PDF report)."""
    from bench.metrology.formatting import format_pair, format_value

    out = frame.astype(object)
    for u_column, columns in _BY_U.items():
        for index, u in frame[u_column].items():
            for column in columns:
                if column in frame:
                    out.at[index, column] = format_value(frame.at[index, column], u)
            out.at[index, u_column] = format_pair(0.0, u)[1]
    for column in ("velocity_pct", "load_kg"):
        if column in frame:
            out[column] = [f"{v:g}" for v in frame[column]]
    return out


def _demo(args: argparse.Namespace) -> int:
    from bench import __version__
    from bench.commands.campaign import execute
    from bench.launch import CAMPAIGN_KERNEL_WAIT_S, simulated_rig_in
    from bench.protocols import Runner
    from bench.protocols.iso9283 import PoseAccuracy
    from bench.store import Store, export_run

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.cycles < 2:
        raise ConfigError(f"--cycles = {args.cycles}, expected an integer >= 2")
    protocol = PoseAccuracy(source="bench demo", cycles=args.cycles)
    started = time.monotonic()
    with Store(out / "bench.db") as store:
        rig = simulated_rig_in(
            store, "pkm5", seed=args.seed, speed_factor=args.speed_factor, kernel_wait_s=CAMPAIGN_KERNEL_WAIT_S
        )
        runner = Runner(rig, store, progress=not args.no_progress)
        result = execute(runner, lambda: runner.run(protocol, campaign="demo"))
        if result.exit_status != "completed":
            raise InsufficientData(f"run {result.run_id} {result.exit_status}: {result.reason}")
        table_path = export_run(store, result.run_id, out / f"run-{result.run_id}.csv")
        results = analyze_run(store, result.run_id)
        results_path = out / "results.csv"
        rounded_results(results).to_csv(results_path, index=False)
        from bench.reports import write_report

        full = write_report(store, result.run_id, out)
    shown = results[
        [c for c in ("pose", "velocity_pct", "n", "AP_mm", "RP_mm", "true_AP_mm", "true_RP_mm") if c in results]
    ]
    print(
        rounded_results(shown.assign(U_AP_mm=results["U_AP_mm"], U_RP_mm=results["U_RP_mm"]))
        .drop(columns=["U_AP_mm", "U_RP_mm"])
        .to_string(index=False),
        file=sys.stderr,
    )
    for path in (out / "bench.db", table_path, results_path, full.html, full.pdf):
        print(path)
    print(f"bench demo: {time.monotonic() - started:.1f} s (bench {__version__})", file=sys.stderr)
    return 0
