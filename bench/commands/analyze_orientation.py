"""``bench analyze orientation``: orientation AP/RP per pose from calliper tilt (or depth) readings, with their GUM
budget (ISO 9283 7.2.1, 7.2.2; `bench.metrology.orientation`)."""

from __future__ import annotations

import argparse

from bench.commands.kin import emit
from bench.errors import ConfigError


def register(actions: argparse._SubParsersAction, new_parser) -> None:
    """Add ``orientation`` to ``bench analyze`` (``new_parser`` adds FILE.csv and --json)."""
    orientation = new_parser(
        actions,
        "orientation",
        "orientation accuracy AP_a/AP_b and repeatability RP_a/RP_b "
        "per pose (ISO 9283 7.2.1, 7.2.2) from calliper tilt readings, "
        "with their GUM budget; reads bench export RUN --kind tilt "
        "(or --kind tilt_depth)",
    )
    orientation.add_argument(
        "--spacing-mm",
        type=float,
        default=None,
        help="hole spacing s of the measuring bracket (mm): tilt = atan2(h2 - h1, s); default "
        "the table's hole_spacing_mm column, else 40",
    )
    orientation.add_argument(
        "--u-spacing-mm",
        type=float,
        default=0.1 / 3**0.5,
        help="standard uncertainty of the hole spacing (mm; default ±0.1 mm rectangular)",
    )
    orientation.add_argument("--resolution-mm", type=float, default=0.01, help="calliper resolution (mm)")
    orientation.add_argument(
        "--mpe-mm", type=float, default=0.02, help="calliper maximum permissible error (mm, rectangular)"
    )
    orientation.add_argument(
        "--bias-deg",
        type=float,
        default=0.0,
        help="measured play bias subtracted from every reading (deg; 000: -4 about y)",
    )
    orientation.add_argument(
        "--u-bias-deg",
        type=float,
        default=0.0,
        help="standard uncertainty of the play-bias correction applied to the readings (deg)",
    )
    orientation.add_argument("--k", type=float, default=2.0, help="coverage factor of the expanded uncertainties")
    orientation.set_defaults(handler=_orientation)


def _orientation(args: argparse.Namespace) -> int:
    from bench.metrology.formatting import format_pair, format_uncertainty, format_value, pose_label, report_order
    from bench.metrology.orientation import TiltGauge
    from bench.metrology.orientation_tables import (
        TILT_NUMERIC_COLUMNS,
        analyze_tilts,
        orientation_summary,
        table_spacing_mm,
        tilt_result_json,
        tilt_table,
    )
    from bench.metrology.tables import read_table_csv

    frame = read_table_csv(args.file, numeric=TILT_NUMERIC_COLUMNS)
    stored = table_spacing_mm(frame)
    if stored is not None and args.spacing_mm is not None and stored != args.spacing_mm:
        raise ConfigError(
            f"--spacing-mm {args.spacing_mm:g}: the readings of {args.file} were taken with "
            f"hole_spacing_mm = {stored:g}, expected that spacing or none"
        )
    spacing = args.spacing_mm if args.spacing_mm is not None else stored if stored is not None else 40.0
    gauge = TiltGauge(
        spacing_mm=spacing,
        u_spacing_mm=args.u_spacing_mm,
        resolution_mm=args.resolution_mm,
        mpe_mm=args.mpe_mm,
        u_bias_deg=args.u_bias_deg,
        bias_deg=args.bias_deg,
    )
    table = tilt_table(frame, gauge.spacing_mm)
    if table.empty:
        raise ConfigError(f"{args.file}: no rows, expected at least one tilt reading")
    results = report_order(analyze_tilts(table, gauge, k=args.k))
    labels = [pose_label(r.pose, r.conditions) for r in results]
    width = max([8, *map(len, labels)])
    lines = [
        f"{'pose':<{width}} {'n':>3} {'angle':>5} {'cmd_deg':>8} {'AP_deg':>8} {'U_AP':>6} {'RP_deg':>7} {'U_RP':>6}"
    ]
    for r, label in zip(results, labels):
        for f in r.figures:
            lines.append(
                f"{label:<{width}} {f.n:>3} {f.angle:>5} {f.commanded_deg:>8g} "
                f"{format_value(f.ap_deg, f.u_ap_deg, signed=True):>8} {format_pair(0, f.u_ap_deg)[1]:>6} "
                f"{format_value(f.rp_deg, f.u_rp_deg):>7} {format_pair(0, f.u_rp_deg)[1]:>6}"
            )
    lines.append(
        f"AP = mean - command (signed), RP = 3 S; tilt = atan2(h2 - h1, s), s = {gauge.spacing_mm:g} mm, "
        f"u(h) = {format_uncertainty(gauge.u_depth_mm)} mm; U with k = {args.k:g} (--json: full precision and budget)."
    )
    emit(
        {
            "gauge": gauge.as_dict(),
            "summary": orientation_summary(results),
            "poses": {r.label: tilt_result_json(r) for r in results},
        },
        args.json,
        lines,
    )
    return 0
