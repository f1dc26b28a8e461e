"""``bench analyze iso230-2``: ISO 230-2 unidirectional and bidirectional positioning figures per axis.

Reads a table ``target_mm, direction (up/down), reading_mm[, axis]`` (`bench.metrology.bidirectional_tables`);
prints the figures or, with ``--json``, one JSON object with units in its keys; ``--plot FILE.svg|.png`` also
writes the report figure (mean deviations per direction, their ±2s bands and the reversal B_i).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from bench.commands.kin import emit
from bench.errors import ConfigError

_PLOT_FORMATS = (".svg", ".png", ".pdf")


def register(actions: argparse._SubParsersAction, new_parser) -> None:
    """Add ``iso230-2`` to ``bench analyze`` (``new_parser`` adds FILE.csv and --json)."""
    parser = new_parser(
        actions,
        "iso230-2",
        "ISO 230-2 positioning of an axis from bidirectional approaches: "
        "reversal B, repeatability R, systematic error E, M, accuracy A; "
        "FILE.csv has target_mm, direction (up/down), reading_mm[, axis]",
    )
    parser.add_argument("--plot", metavar="FIGURE.svg", default=None, help="also write the figure (.svg, .png or .pdf)")
    parser.set_defaults(handler=_iso230_2)

    run = actions.add_parser(
        "iso230-2-run",
        help="ISO 230-2 B, R, E, M, A per actuator of a stored bidirectional "
        "actuator_accuracy run, from its stored readings",
        description="ISO 230-2 figures per actuator of a stored actuator_accuracy run made with "
        'approach = "bidirectional" (the same as bench export RUN --kind '
        "actuator_travel, then bench analyze iso230-2)",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    run.add_argument("run_id", metavar="RUN_ID", type=int, help="the stored actuator_accuracy run")
    run.add_argument("--store", default="bench.db", help="run store (SQLite file)")
    run.add_argument("--json", action="store_true", help="print the result as one JSON object")
    run.add_argument("--plot", metavar="FIGURE.svg", default=None, help="also write the figure (.svg, .png or .pdf)")
    run.set_defaults(handler=_iso230_2_run)


def result_json(r) -> dict:
    """One axis as ``bench analyze iso230-2 --json`` prints it (mm)."""
    f = r.result
    return {
        "n_up": int(r.forward_mm.shape[0]),
        "n_down": int(r.backward_mm.shape[0]),
        "targets_mm": r.targets_mm.tolist(),
        "mean_deviation_up_mm": list(f.mean_deviation_forward_mm),
        "mean_deviation_down_mm": list(f.mean_deviation_backward_mm),
        "reversal_mm": list(f.reversal_mm),
        "B_mm": f.reversal_max_mm,
        "R_up_mm": f.repeatability_forward_mm,
        "R_down_mm": f.repeatability_backward_mm,
        "R_mm": f.repeatability_mm,
        "E_up_mm": f.systematic_forward_mm,
        "E_down_mm": f.systematic_backward_mm,
        "E_mm": f.systematic_mm,
        "M_mm": f.mean_bidirectional_mm,
        "A_up_mm": f.accuracy_forward_mm,
        "A_down_mm": f.accuracy_backward_mm,
        "A_mm": f.accuracy_mm,
    }


def _iso230_2(args: argparse.Namespace) -> int:
    from bench.metrology.bidirectional_tables import analyze_bidirectional
    from bench.metrology.tables import read_table_csv

    _check_plot(args.plot)
    return _print(analyze_bidirectional(read_table_csv(args.file)), args)


def _iso230_2_run(args: argparse.Namespace) -> int:
    from bench.metrology.bidirectional_tables import analyze_bidirectional
    from bench.store import Store, tidy_table

    _check_plot(args.plot)
    store = Store(args.store, read_only=True)
    try:
        run = store.run(args.run_id)
        if run.protocol_name != "actuator_accuracy" or run.config.get("approach") != "bidirectional":
            raise ConfigError(
                f"run {args.run_id}: a {run.protocol_name} run"
                + (" with unidirectional approaches" if run.protocol_name == "actuator_accuracy" else "")
                + ', expected an actuator_accuracy run with approach = "bidirectional"'
            )
        table = tidy_table(store, args.run_id, kind="actuator_travel")
    finally:
        store.close()
    table.attrs["source"] = f"run {args.run_id}"
    return _print(analyze_bidirectional(table), args)


def _check_plot(plot: str | None) -> None:
    if plot is not None and Path(plot).suffix.lower() not in _PLOT_FORMATS:
        raise ConfigError(f"--plot {plot}: expected a file name ending in {', '.join(_PLOT_FORMATS)}")


def _print(results, args: argparse.Namespace) -> int:
    axes = {r.axis: result_json(r) for r in results}
    lines = [f"{'axis':<6} {'B_mm':>8} {'R_mm':>8} {'R↑_mm':>8} {'R↓_mm':>8} {'E_mm':>8} {'M_mm':>8} {'A_mm':>8}"]
    for r in results:
        f = r.result
        lines.append(
            f"{r.axis:<6} {f.reversal_max_mm:>8.4f} {f.repeatability_mm:>8.4f} "
            f"{f.repeatability_forward_mm:>8.4f} {f.repeatability_backward_mm:>8.4f} {f.systematic_mm:>8.4f} "
            f"{f.mean_bidirectional_mm:>8.4f} {f.accuracy_mm:>8.4f}"
        )
    lines.append("ISO 230-2 with s over the approaches (n - 1); R_i = max(2s↑ + 2s↓ + |B_i|, R↑_i, R↓_i).")
    if args.plot is not None:
        from bench.reports.bidirectional import bidirectional_plot

        plot = bidirectional_plot(results)
        try:
            plot.figure.savefig(args.plot, metadata={"Date": None} if args.plot.endswith(".svg") else None)
        except OSError as exc:
            raise ConfigError(f"--plot {args.plot}: cannot write ({exc.strerror})") from None
        lines.append(f"figure written to {args.plot}")
    emit({"axes": axes}, args.json, lines)
    return 0
