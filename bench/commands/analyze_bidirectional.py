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
    parser = new_parser(actions, "iso230-2", "ISO 230-2 positioning of an axis from bidirectional approaches: "
                                             "reversal B, repeatability R, systematic error E, M, accuracy A; "
                                             "FILE.csv has target_mm, direction (up/down), reading_mm[, axis]")
    parser.add_argument("--plot", metavar="FIGURE.svg", default=None,
                        help="also write the figure (.svg, .png or .pdf)")
    parser.set_defaults(handler=_iso230_2)


def result_json(r) -> dict:
    """One axis as ``bench analyze iso230-2 --json`` prints it (mm)."""
    f = r.result
    return {"n_up": int(r.forward_mm.shape[0]), "n_down": int(r.backward_mm.shape[0]),
            "targets_mm": r.targets_mm.tolist(),
            "mean_deviation_up_mm": list(f.mean_deviation_forward_mm),
            "mean_deviation_down_mm": list(f.mean_deviation_backward_mm),
            "reversal_mm": list(f.reversal_mm), "B_mm": f.reversal_max_mm,
            "R_up_mm": f.repeatability_forward_mm, "R_down_mm": f.repeatability_backward_mm,
            "R_mm": f.repeatability_mm, "E_up_mm": f.systematic_forward_mm, "E_down_mm": f.systematic_backward_mm,
            "E_mm": f.systematic_mm, "M_mm": f.mean_bidirectional_mm, "A_up_mm": f.accuracy_forward_mm,
            "A_down_mm": f.accuracy_backward_mm, "A_mm": f.accuracy_mm}


def _iso230_2(args: argparse.Namespace) -> int:
    from bench.metrology.bidirectional_tables import analyze_bidirectional
    from bench.metrology.tables import read_table_csv

    if args.plot is not None and Path(args.plot).suffix.lower() not in _PLOT_FORMATS:
        raise ConfigError(f"--plot {args.plot}: expected a file name ending in {', '.join(_PLOT_FORMATS)}")
    results = analyze_bidirectional(read_table_csv(args.file))
    axes = {r.axis: result_json(r) for r in results}
    lines = [f"{'axis':<6} {'B_mm':>8} {'R_mm':>8} {'R↑_mm':>8} {'R↓_mm':>8} {'E_mm':>8} {'M_mm':>8} {'A_mm':>8}"]
    for r in results:
        f = r.result
        lines.append(f"{r.axis:<6} {f.reversal_max_mm:>8.4f} {f.repeatability_mm:>8.4f} "
                     f"{f.repeatability_forward_mm:>8.4f} {f.repeatability_backward_mm:>8.4f} {f.systematic_mm:>8.4f} "
                     f"{f.mean_bidirectional_mm:>8.4f} {f.accuracy_mm:>8.4f}")
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
