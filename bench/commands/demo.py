"""``bench demo``: the main job end to end on a fresh install, in well under a minute.

Starts the simulated pkm5 controller (a separate process on a pseudo-terminal) and the simulated optical mice,
runs a complete ISO 9283 pose campaign (P1-P5 of the largest cube in the workspace, 30 cycles, 100/50/10 %
velocity) with the simulator's speed factor, stores every sample in ``OUT/bench.db``, exports the tidy table,
analyses it with :mod:`bench.metrology`, and writes ``OUT/results.csv`` and ``OUT/report.md`` (a quick table that
also compares the measured AP/RP with the simulator's true attained poses) and the full report of
:mod:`bench.reports` (``OUT/report_run<ID>.html`` and ``.pdf``).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from bench.errors import ConfigError, InsufficientData

if TYPE_CHECKING:  # imported inside the functions: building the parser stays cheap
    import pandas as pd

    from bench.protocols.iso9283 import PoseAccuracy
    from bench.store import Store

__all__ = ["analyze_run", "register", "rounded_results"]


def register(groups: argparse._SubParsersAction) -> None:
    demo = groups.add_parser("demo", help="simulated ISO 9283 pose campaign on the pkm5, analysed, in < 1 min",
                             description=__doc__.splitlines()[0],
                             formatter_class=argparse.ArgumentDefaultsHelpFormatter)
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
    instrument settings, :func:`bench.reports.content.counts_instrument`), so results.csv, report.md and the
    HTML/PDF give the same U.
    """
    import pandas as pd

    from bench.metrology.formatting import report_order
    from bench.metrology.tables import analyze_poses, pose_result_json, pose_table
    from bench.reports.content import analysis_table, calibrations_in_force, counts_instrument

    table = analysis_table(store, run_id)
    run = store.run(run_id)
    instrument = counts_instrument(run, calibrations_in_force(store, run),
                                   dims=sum(c in table.columns for c in ("x_mm", "y_mm", "z_mm")))
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


def _markdown(frame: pd.DataFrame) -> str:
    header = "| " + " | ".join(frame.columns) + " |\n|" + "---|" * len(frame.columns) + "\n"
    body = "".join("| " + " | ".join(str(v) for v in row) + " |\n" for row in frame.itertuples(index=False))
    return header + body


def _report(store: Store, run_id: int, protocol: PoseAccuracy, results: pd.DataFrame, elapsed_s: float) -> str:
    run = store.run(run_id)
    calibrations = ", ".join(f"{c.name} v{c.version} (id {c.id})" for c in store.calibrations()
                             if c.id in run.calibration_ids)
    poses = "; ".join(f"{k} = ({', '.join(f'{v:.2f}' for v in p)}) mm" for k, p in protocol.test_poses().items())
    lines = [
        "# ISO 9283-style pose accuracy and repeatability: simulated pkm5",
        "",
        ("Tested following the methods of ISO 9283:1998 with the deviations listed below; results are "
        "\"ISO 9283-style\", not certified. No pass/fail criterion is configured, so none is given."),
        "",
        "## Provenance",
        (f"- run {run_id}, protocol {run.protocol_name} v{run.protocol_version}, status {run.status}, "
        f"{run.n_samples} samples, {elapsed_s:.1f} s wall time"),
        f"- bench {run.software_version}, git {run.git_sha}; store `{store.path}`",
        (f"- simulator seed {run.settings.get('simulator', {}).get('seed')}, speed factor "
        f"{run.settings.get('speed_factor'):g}; calibrations: {calibrations or 'none'}"),
        f"- configuration: `{json.dumps(run.config, sort_keys=True)}`",
        "",
        "## Test conditions",
        (f"- cube centre {list(protocol.cube_centre_mm)} mm, edge {protocol.resolved()['cube_side_mm']:g} mm "
        f"(largest cube whose 27 lattice points pass the pre-flight), plane {protocol.plane}"),
        f"- poses: {poses}",
        (f"- order P1 -> P5 -> P4 -> P3 -> P2, unidirectional; {protocol.cycles} cycles; velocities "
        f"{', '.join(f'{v:g}' for v in protocol.velocities_pct)} % of 200 steps/s; dwell {protocol.settle_s:g} s"),
        "",
        "## Deviations from ISO 9283",
        "| Clause | ISO requirement | What was done | Reason | Expected effect |",
        "|---|---|---|---|---|",
        ("| 6.6 | 100 % rated load | no payload (the pkm5 has no rated load) | no specification | AP/RP optimistic "
        "for loaded use |"),
        ("| 6.7 | rated velocity | 100 % = the documents' firmware speed, 200 steps/s | no rated velocity | "
        "velocities not comparable with other robots |"),
        (f"| 6.8 | largest cube in the working space | {protocol.resolved()['cube_side_mm']:g} mm cube | small "
        "workspace with 60 mm leg windows | not comparable with other robots |"),
        ("| 6.5 | instrument uncertainty << RP | two optical mice, 800 cpi (0.032 mm/count), simulated | low-cost "
        "bench | RP includes the instrument floor |"),
        "| 6.2, 6.3 | warm-up, temperature recorded | simulated; none | simulation | none |",
        "",
        "## Results (mm; U at k = 2; values rounded by their U)",
        _markdown(rounded_results(results)),
    ]
    if "true_AP_mm" in results:
        worst_ap = (results["AP_mm"] - results["true_AP_mm"]).abs().max()
        worst_rp = (results["RP_mm"] - results["true_RP_mm"]).abs().max()
        lines += ["## Simulation check",
                  (f"Measured against the simulator's true attained poses: largest |AP - AP_true| = "
                  f"{worst_ap:.3f} mm, largest |RP - RP_true| = {worst_rp:.3f} mm (instrument quantisation "
                  "and noise)."), ""]
    return "\n".join(lines)


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
        rig = simulated_rig_in(store, "pkm5", seed=args.seed, speed_factor=args.speed_factor,
                               kernel_wait_s=CAMPAIGN_KERNEL_WAIT_S)
        runner = Runner(rig, store, progress=not args.no_progress)
        result = execute(runner, lambda: runner.run(protocol, campaign="demo"))
        if result.exit_status != "completed":
            raise InsufficientData(f"run {result.run_id} {result.exit_status}: {result.reason}")
        table_path = export_run(store, result.run_id, out / f"run-{result.run_id}.csv")
        results = analyze_run(store, result.run_id)
        results_path = out / "results.csv"
        rounded_results(results).to_csv(results_path, index=False)
        report_path = out / "report.md"
        report_path.write_text(_report(store, result.run_id, protocol, results, time.monotonic() - started),
                               encoding="utf-8")
        from bench.reports import write_report
        full = write_report(store, result.run_id, out)
    shown = results[[c for c in ("pose", "velocity_pct", "n", "AP_mm", "RP_mm", "true_AP_mm", "true_RP_mm")
                     if c in results]]
    print(rounded_results(shown.assign(U_AP_mm=results["U_AP_mm"], U_RP_mm=results["U_RP_mm"]))
          .drop(columns=["U_AP_mm", "U_RP_mm"]).to_string(index=False), file=sys.stderr)
    for path in (out / "bench.db", table_path, results_path, report_path, full.html, full.pdf):
        print(path)
    print(f"bench demo: {time.monotonic() - started:.1f} s (bench {__version__})", file=sys.stderr)
    return 0
