"""``bench analyze``: metrology figures from tidy CSV tables: ISO 9283 poses, distance, drift and stabilisation here;
actuators and payload in `bench.commands.analyze_actuator`, the mouse's resolution in `bench.commands.analyze_mouse`,
the laser grid in `bench.commands.analyze_grid`, vAP, paths, cornering, path velocity and positioning time in
`bench.commands.analyze_path`, ISO 230-2 in `bench.commands.analyze_bidirectional`, orientation from calliper tilts
in `bench.commands.analyze_orientation`.

Every handler reads a CSV through `bench.metrology.tables`, computes with `bench.metrology`, and prints a readable
table or, with ``--json``, one JSON object on stdout. Bad cells give a one-line ``ConfigError`` naming the row,
column and value (exit 2); a pose with too few cycles gives ``InsufficientData`` (exit 1).
"""

from __future__ import annotations

import argparse

from bench.commands.kin import emit
from bench.errors import ConfigError

# numpy, pandas and bench.metrology are imported inside the handlers: building the parser stays cheap.


def register(groups: argparse._SubParsersAction) -> None:
    analyze = groups.add_parser("analyze", help="metrology figures from CSV sample tables (mm, degrees)")
    actions = analyze.add_subparsers(dest="action", metavar="ANALYSIS", required=True)

    iso = _new_parser(actions, "iso9283", "pose accuracy AP and repeatability RP per pose (ISO 9283 7.2)")
    iso.add_argument(
        "--instrument-u-mm",
        type=float,
        default=None,
        help="instrument standard uncertainty per axis (mm, from the station file or the calibration "
        "in force), added to the AP budget; without it U excludes the instrument and says so",
    )
    iso.add_argument("--k", type=float, default=2.0, help="coverage factor of the expanded uncertainties")
    iso.add_argument(
        "--chunk-rows",
        type=int,
        default=None,
        metavar="ROWS",
        help="read the table this many rows at a time (memory: one chunk and the largest pose; the same figures); "
        "default: whole below 128 MiB, 2^20 rows at a time above",
    )
    iso.set_defaults(handler=_iso9283)

    distance = _new_parser(actions, "distance", "distance accuracy AD and repeatability RD (ISO 9283 7.3)")
    distance.add_argument("--from", dest="first", default="P2", help="first command pose")
    distance.add_argument("--to", dest="second", default="P4", help="second command pose")
    distance.add_argument(
        "--instrument-u-mm",
        type=float,
        default=None,
        help="instrument standard uncertainty of one position reading (mm); without it U "
        "excludes the instrument and says so",
    )
    distance.set_defaults(handler=_distance)

    drift = _new_parser(actions, "drift", "drift dAP/dRP of one pose over time windows (ISO 9283 7.6), needs t_s")
    drift.add_argument("--pose", default="P1", help="the pose to analyse")
    drift.add_argument("--window-s", type=float, default=3600.0, help="window length (s)")
    drift.set_defaults(handler=_drift)

    settling = _new_parser(
        actions,
        "stabilisation",
        "position stabilisation time and overshoot per pose (ISO 9283 7.4, 7.5); reads bench export RUN --series",
    )
    settling.add_argument(
        "--band-mm",
        type=float,
        nargs="+",
        default=[0.1, 0.5, 1.0],
        help="limit bands B (mm); ISO comparison bands 0.1, 0.5, 1.0",
    )
    settling.add_argument(
        "--hysteresis-mm",
        type=float,
        default=0.0,
        help="excursions up to this far beyond the band are not counted (set it to the "
        "instrument's resolution, e.g. one mouse count 25.4/CPI mm; 0 = ISO as written)",
    )
    settling.set_defaults(handler=_stabilisation)

    from bench.commands.analyze_actuator import register as register_actuator
    from bench.commands.analyze_bidirectional import register as register_bidirectional
    from bench.commands.analyze_grid import register as register_grid
    from bench.commands.analyze_mouse import register as register_mouse
    from bench.commands.analyze_orientation import register as register_orientation
    from bench.commands.analyze_path import register as register_paths
    from bench.commands.analyze_path import register_run as register_path_run

    register_actuator(actions, _new_parser)
    register_mouse(actions, _new_parser)
    register_grid(actions, _new_parser)
    register_paths(actions, _new_parser)
    register_path_run(actions)
    register_bidirectional(actions, _new_parser)
    register_orientation(actions, _new_parser)


def _new_parser(actions: argparse._SubParsersAction, name: str, text: str) -> argparse.ArgumentParser:
    parser = actions.add_parser(
        name, help=text, description=text, formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    parser.add_argument("file", metavar="FILE.csv", help="tidy CSV table, one row per sample")
    parser.add_argument("--json", action="store_true", help="print the result as one JSON object")
    return parser


def _iso9283(args: argparse.Namespace) -> int:
    from bench.metrology.formatting import format_pair, format_value, pose_label, report_order
    from bench.metrology.pose_stream import pose_file_results
    from bench.metrology.tables import pose_result_json
    from bench.metrology.uncertainty import instrument_budget

    if args.chunk_rows is not None and args.chunk_rows < 1:
        raise ConfigError(f"--chunk-rows {args.chunk_rows}: expected a number of rows >= 1")
    budget = instrument_budget(args.instrument_u_mm, "--instrument-u-mm")
    results = report_order(
        pose_file_results(args.file, instrument_u_mm=args.instrument_u_mm or 0.0, k=args.k, chunk_rows=args.chunk_rows)
    )
    labels = [pose_label(r.pose, r.conditions) for r in results]
    width = max([12, *map(len, labels)])
    lines = [
        (
            f"{'pose':<{width}} {'n':>3} {'AP_mm':>8} {'APx_mm':>8} {'APy_mm':>8} {'APz_mm':>8} {'RP_mm':>8} "
            f"{'U_AP':>7} {'U_RP':>7}"
        )
    ]
    for r, label in zip(results, labels):
        u_ap, u_rp = r.ap_u.expanded_uncertainty, r.rp_u.expanded_uncertainty
        measured = dict(zip(r.axis_names, r.accuracy.ap_axes_mm))
        ap, ax, ay, az = (
            format_value(v, u_ap) if v is not None else "n/m"
            for v in (r.accuracy.ap_mm, *(measured.get(a) for a in "xyz"))
        )
        lines.append(
            f"{label:<{width}} {r.accuracy.n:>3} {ap:>8} {ax:>8} {ay:>8} {az:>8} "
            f"{format_value(r.repeatability.rp_mm, u_rp):>8} {format_pair(0, u_ap)[1]:>7} "
            f"{format_pair(0, u_rp)[1]:>7}"
        )
        if r.orientation_accuracy is not None:
            text = ", ".join(
                f"AP{n} {ap:+.3f} RP{n} ±{rp:.3f}"
                for n, ap, rp in zip(r.angle_names, r.orientation_accuracy.ap_deg, r.orientation_repeatability.rp_deg)
            )
            lines.append(f"{'':<{width}} orientation (deg): {text}")
    axes = results[0].axis_names if results else ("x", "y", "z")
    if len(axes) < 3:
        missing = ", ".join(c for c in "xyz" if c not in axes)
        lines.append(
            f"AP and RP over the measured axes {', '.join(axes)} only ({missing} not in {args.file}: n/m, "
            "not measured); not the 3-D figures."
        )
    lines.append(
        f"AP against the commanded pose; RP = l̄ + 3 S_l; U for the coverage of k = {args.k:g}: U_AP the "
        f"cycles' scatter (Student's k at ν_eff) and the instrument, U_RP a Monte Carlo of the measurement "
        f"model (docs/metrology.md); values rounded by their U (--json: full precision)."
    )
    lines.append(budget + ".")
    emit({"poses": {r.label: pose_result_json(r) for r in results}, "U_budget": budget}, args.json, lines)
    return 0


def _distance(args: argparse.Namespace) -> int:
    from bench.metrology.formatting import format_length
    from bench.metrology.tables import (
        POSE_NUMERIC_COLUMNS,
        analyze_distance,
        analyze_orientation_distance,
        pose_table,
        read_table_csv,
    )
    from bench.metrology.uncertainty import distance_accuracy_uncertainty, instrument_budget
    from bench.metrology.uncertainty_figures import spread_uncertainty

    table = pose_table(read_table_csv(args.file, numeric=POSE_NUMERIC_COLUMNS))
    r = analyze_distance(table, args.first, args.second)
    budget = instrument_budget(args.instrument_u_mm, "--instrument-u-mm")
    u_ad = distance_accuracy_uncertainty(r.ad_mm, r.u_ad_mm, r.n, instrument_u_mm=args.instrument_u_mm or 0.0)
    u_rd = spread_uncertainty(r.rd_mm, r.n, unit="mm")
    result = {
        "from": args.first,
        "to": args.second,
        "n": r.n,
        "AD_mm": r.ad_mm,
        "U_AD_mm": u_ad.expanded_uncertainty,
        "k": u_ad.coverage_factor,
        "RD_mm": r.rd_mm,
        "U_RD_mm": u_rd.expanded_uncertainty,
        "AD_axes_mm": list(r.ad_axes_mm),
        "RD_axes_mm": list(r.rd_axes_mm),
        "mean_distance_mm": r.mean_distance_mm,
        "commanded_distance_mm": r.commanded_distance_mm,
        "U_budget": budget,
    }
    lines = [
        (
            f"{args.first} -> {args.second}, n = {r.n}: D_c = {r.commanded_distance_mm:.3f} mm, "
            f"D̄ = {r.mean_distance_mm:.3f} mm"
        ),
        f"AD_p = {u_ad}, RD = {u_rd} (values rounded by their U); {budget}",
        "AD x/y/z = "
        + " / ".join(format_length(v, signed=True) for v in r.ad_axes_mm)
        + " mm, RD x/y/z = ±"
        + " / ±".join(map(format_length, r.rd_axes_mm))
        + " mm",
    ]
    angles = analyze_orientation_distance(table, args.first, args.second)
    if angles is not None:
        names, o = angles
        for name, ad, rd in zip(names, o.ad_deg, o.rd_deg):
            result[f"AD_{name}_deg"], result[f"RD_{name}_deg"] = ad, rd
        lines.append(
            "orientation: "
            + ", ".join(
                f"AD_{n} {format_length(ad, signed=True)} deg, RD_{n} ±{format_length(rd)} deg"
                for n, ad, rd in zip(names, o.ad_deg, o.rd_deg)
            )
        )
    emit(result, args.json, lines)
    return 0


def _drift(args: argparse.Namespace) -> int:
    from bench.metrology import orientation_drift, pose_drift
    from bench.metrology.formatting import format_length
    from bench.metrology.tables import ANGLE_PAIRS, POSE_NUMERIC_COLUMNS, pose_table, read_table_csv

    table = pose_table(read_table_csv(args.file, numeric=POSE_NUMERIC_COLUMNS))
    if "t_s" not in table.columns:
        raise ConfigError(f"{args.file}: missing column t_s, needed for drift")
    rows = table[table["pose"] == args.pose]
    if rows.empty:
        raise ConfigError(f"{args.file}: pose {args.pose!r} not found; poses: {', '.join(table['pose'].unique())}")
    r = pose_drift(
        rows["t_s"],
        rows[["x_mm", "y_mm", "z_mm"]],
        rows[["cmd_x_mm", "cmd_y_mm", "cmd_z_mm"]].to_numpy()[0],
        window_s=args.window_s,
    )
    result = {
        "pose": args.pose,
        "dAP_mm": r.dap_mm,
        "dRP_mm": r.drp_mm,
        "windows": [
            {"t_start_s": float(t), "n": int(n), "AP_mm": float(a), "RP_mm": float(p)}
            for t, n, a, p in zip(r.window_start_s, r.n_per_window, r.ap_mm, r.rp_mm)
        ],
    }
    mm = format_length
    lines = [f"pose {args.pose}: dAP = {mm(r.dap_mm)} mm, dRP = {mm(r.drp_mm)} mm over {len(r.ap_mm)} windows"]
    lines += [
        f"  t >= {t:10.1f} s  n = {n:4d}  AP = {mm(a)} mm  RP = {mm(p)} mm"
        for t, n, a, p in zip(r.window_start_s, r.n_per_window, r.ap_mm, r.rp_mm)
    ]
    pairs = [(c, a) for c, a in ANGLE_PAIRS if a in rows.columns]
    if pairs:
        o = orientation_drift(
            rows["t_s"], rows[[a for _, a in pairs]], rows[[c for c, _ in pairs]].to_numpy()[0], window_s=args.window_s
        )
        for i, (_, column) in enumerate(pairs):
            name = column[0]
            result[f"dAP_{name}_deg"], result[f"dRP_{name}_deg"] = o.dap_deg[i], o.drp_deg[i]
            for window, ap, rp in zip(result["windows"], o.ap_deg[:, i], o.rp_deg[:, i]):
                window[f"AP_{name}_deg"], window[f"RP_{name}_deg"] = float(ap), float(rp)
            lines.append(
                f"  orientation {name}: dAP_{name} = {mm(o.dap_deg[i])} deg, dRP_{name} = {mm(o.drp_deg[i])} deg"
            )
    emit(result, args.json, lines)
    return 0


def _stabilisation(args: argparse.Namespace) -> int:
    from bench.metrology.formatting import format_length
    from bench.metrology.stabilisation_tables import stabilisation_results, stabilisation_table
    from bench.metrology.table_reading import read_table_csv

    table = stabilisation_table(read_table_csv(args.file))
    for band in args.band_mm:
        if not band > 0:
            raise ConfigError(f"--band-mm {band:g}: expected limit bands > 0 mm")
    figures = stabilisation_results(table, args.band_mm, args.hysteresis_mm)
    result: dict = {"hysteresis_mm": args.hysteresis_mm, "bands": {}}
    width = max([6, *(len(label) for label in figures.series)])
    lines = [f"{'band_mm':>7}  {'pose':<{width}} {'n':>2} {'mean_t_s':>8} {'max_t_s':>8} {'OV_mm':>7} {'max_OV_mm':>9}"]
    for band, per_pose in figures.bands.items():
        printed = result["bands"][f"{band:g}"] = {}
        for pose, r in per_pose.items():
            n = len(figures.series[pose])
            if isinstance(r, str):
                printed[pose] = {"n": n, "error": r}
                lines.append(f"{band:>7g}  {pose:<{width}} {n:>2} {r}")
                continue
            printed[pose] = {
                "n": n,
                "mean_time_s": r.mean_time_s,
                "max_time_s": r.max_time_s,
                "overshoot_mm": r.mean_overshoot_mm,
                "max_overshoot_mm": r.max_overshoot_mm,
                "time_s_per_cycle": [c.stabilisation_time_s for c in r.cycles],
                "overshoot_mm_per_cycle": [c.overshoot_mm for c in r.cycles],
            }
            lines.append(
                f"{band:>7g}  {pose:<{width}} {n:>2} {r.mean_time_s:>8.3f} {r.max_time_s:>8.3f} "
                f"{format_length(r.mean_overshoot_mm):>7} {format_length(r.max_overshoot_mm):>9}"
            )
    emit(result, args.json, lines)
    return 0
