"""``bench analyze``: metrology figures from tidy CSV tables (ISO 9283 poses, distance, drift, actuators, payload;
vAP, paths, cornering, path velocity and positioning time in `bench.commands.analyze_path`, ISO 230-2 in
`bench.commands.analyze_bidirectional`, orientation from calliper tilts in `bench.commands.analyze_orientation`, the
mouse's resolution in `bench.commands.analyze_mouse`).

Every handler reads a CSV through `bench.metrology.tables`, computes with `bench.metrology`, and prints a readable
table or, with ``--json``, one JSON object on stdout. Bad cells give a one-line ``ConfigError`` naming the row,
column and value (exit 2); a pose with too few cycles gives ``InsufficientData`` (exit 1).
"""

from __future__ import annotations

import argparse

from bench.commands.kin import emit
from bench.commands.lazy import defer
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

    actuator = _new_parser(
        actions,
        "actuator",
        "actuator repeatability/accuracy (Groover), mean bias and ISO 230-2 "
        "unidirectional figures; reads bench export --kind actuator_travel",
    )
    actuator.add_argument(
        "--cr-mm", type=float, default=None, help="control resolution (mm/step) when the table has no cr_mm column"
    )
    defer(actuator, _add_actuator_robot)
    actuator.add_argument(
        "--instrument-u-mm",
        type=float,
        default=None,
        help="instrument standard uncertainty of one travel reading (mm); without it U "
        "excludes the instrument and says so",
    )
    actuator.add_argument("--k", type=float, default=2.0, help="coverage factor of the expanded uncertainties")
    actuator.set_defaults(handler=_actuator)

    payload = _new_parser(actions, "payload", "leg actuation error against load (project payload error)")
    payload.set_defaults(handler=_payload)

    from bench.commands.analyze_mouse import register as register_mouse

    register_mouse(actions, _new_parser)

    grid = _new_parser(
        actions,
        "grid-positioning",
        "delta robot read by the laser grid: hit rate per screen and "
        "per-axis AP, 3 S, max/mean |error| over the readings that "
        "measured each axis (delta_positioning runs)",
    )
    grid.add_argument("--k", type=float, default=2.0, help="coverage factor: z of the rates' Wilson intervals")
    grid.set_defaults(handler=_grid_positioning)

    from bench.commands.analyze_bidirectional import register as register_bidirectional
    from bench.commands.analyze_orientation import register as register_orientation
    from bench.commands.analyze_path import register as register_paths
    from bench.commands.analyze_path import register_run as register_path_run

    register_paths(actions, _new_parser)
    register_path_run(actions)
    register_bidirectional(actions, _new_parser)
    register_orientation(actions, _new_parser)


def _add_actuator_robot(parser: argparse.ArgumentParser) -> None:
    from bench.metrology.actuator_tables import ACTUATOR_ROBOTS

    parser.add_argument(
        "--robot",
        choices=ACTUATOR_ROBOTS,
        default=None,
        help="control resolution per actuator number from this robot's model (an "
        "actuator_accuracy export: --robot pkm5)",
    )


def _new_parser(actions: argparse._SubParsersAction, name: str, text: str) -> argparse.ArgumentParser:
    parser = actions.add_parser(
        name, help=text, description=text, formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    parser.add_argument("file", metavar="FILE.csv", help="tidy CSV table, one row per sample")
    parser.add_argument("--json", action="store_true", help="print the result as one JSON object")
    return parser


def _iso9283(args: argparse.Namespace) -> int:
    from bench.metrology.formatting import format_pair, format_value, pose_label, report_order
    from bench.metrology.tables import (
        POSE_NUMERIC_COLUMNS,
        analyze_poses,
        pose_result_json,
        pose_table,
        read_table_csv,
    )

    frame = read_table_csv(args.file, numeric=POSE_NUMERIC_COLUMNS)
    if "horizontal_valid" in frame.columns:  # the laser grid: partial readings, as bench report lays them out
        raise ConfigError(
            f"{args.file}: laser-grid readings (column horizontal_valid; axes empty where a screen did "
            f"not decode), expected complete readings; analyse them with bench analyze "
            f"grid-positioning {args.file}"
        )
    # an instrument that measures a subset of the axes (the camera: x, y): AP/RP over those, as bench report does
    table = pose_table(frame, partial_axes=True)
    if table.empty:  # a header and no rows: nothing measured, never an empty result printed as if it were one
        raise ConfigError(f"{args.file}: no rows, expected at least one measured pose")
    from bench.metrology.uncertainty import instrument_budget

    budget = instrument_budget(args.instrument_u_mm, "--instrument-u-mm")
    results = report_order(analyze_poses(table, instrument_u_mm=args.instrument_u_mm or 0.0, k=args.k))
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
    from bench.metrology.table_csv import read_table_csv

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


def actuator_result_json(r) -> dict:
    """One actuator's figures as ``bench analyze actuator --json`` prints them (mm; U with the coverage factor k)."""
    g, iso = r.groover, r.iso230_2
    return {
        "n": g.n,
        "targets_mm": list(r.targets_mm),
        "repeatability_mm": g.repeatability_mm,
        "accuracy_mm": g.accuracy_mm,
        "control_resolution_mm": r.control_resolution_mm,
        "sigma_mm": list(g.sigma_mm),
        "mean_deviation_mm": list(g.mean_deviation_mm),
        "U_mean_deviation_mm": [m.expanded_uncertainty for m in r.bias_u],
        "k": r.bias_u[0].coverage_factor,
        "U_repeatability_mm": None if r.repeatability_u is None else r.repeatability_u.expanded_uncertainty,
        "U_accuracy_mm": None if r.accuracy_u is None else r.accuracy_u.expanded_uncertainty,
        "max_abs_bias_mm": g.max_abs_bias_mm,
        "dropped_readings": r.dropped,
        "iso230_2_forward": {
            "R_mm": iso.repeatability_forward_mm,
            "E_mm": iso.systematic_forward_mm,
            "A_mm": iso.accuracy_forward_mm,
        },
    }


def _actuator(args: argparse.Namespace) -> int:
    from bench.metrology.actuator_tables import actuator_table, analyze_actuators, robot_control_resolution
    from bench.metrology.formatting import format_value, reading_step_mm
    from bench.metrology.tables import read_table_csv
    from bench.metrology.uncertainty import instrument_budget

    budget = instrument_budget(args.instrument_u_mm, "--instrument-u-mm")

    frame = read_table_csv(args.file)
    resolution = (
        args.cr_mm
        if args.cr_mm is not None
        else (robot_control_resolution(args.robot) if args.robot is not None else None)
    )
    if "cr_mm" not in frame.columns and resolution is None:
        raise ConfigError(
            f"{args.file}: no cr_mm column and no --cr-mm given, expected one of them (an "
            "actuator_accuracy export: --robot pkm5)"
        )
    results = analyze_actuators(
        actuator_table(frame), control_resolution_mm=resolution, instrument_u_mm=args.instrument_u_mm or 0.0, k=args.k
    )
    lines = [
        (
            f"{'actuator':<9} {'n':>3} {'repeat_mm':>9} {'accuracy_mm':>11} {'max|bias|_mm':>12} {'R230_mm':>8} "
            f"{'E230_mm':>8} {'A230_mm':>8}  mean deviation per target (mm)"
        )
    ]
    step = reading_step_mm(frame["travel_mm"]) if "travel_mm" in frame else None

    def mm(value: float, u: float | None = None, signed: bool = False) -> str:
        """By its U when it has one, else never finer than the readings (as the report: figure_decimals)."""
        return format_value(value, u, signed=signed, resolution=None if u is not None else step)

    for r in results:
        g, iso = r.groover, r.iso230_2
        repeat_u, accuracy_u = (
            None if m is None else m.expanded_uncertainty for m in (r.repeatability_u, r.accuracy_u)
        )
        lines.append(
            f"{r.actuator:<9} {g.n:>3} {mm(g.repeatability_mm, repeat_u):>9} "
            f"{mm(g.accuracy_mm, accuracy_u):>11} {mm(g.max_abs_bias_mm):>12} "
            f"{mm(iso.repeatability_forward_mm):>8} {mm(iso.systematic_forward_mm):>8} {mm(iso.accuracy_forward_mm):>8}  "
            + " ".join(mm(v, u.expanded_uncertainty, True) for v, u in zip(g.mean_deviation_mm, r.bias_u))
            + (f"  ({r.dropped} readings of incomplete repeats left out)" if r.dropped else "")
        )
    lines.append(
        "Repeatability = 3 σ̄, accuracy = CR/2 + 3 σ̄ (dissertation Eqs. 8.2-8.3); bias = x̄ - target; "
        "R/E/A: ISO 230-2 unidirectional (approach from below); figures with a U rounded by it (--json: U, full precision)."
    )
    lines.append(budget + ".")
    emit({"actuators": {r.actuator: actuator_result_json(r) for r in results}, "U_budget": budget}, args.json, lines)
    return 0


def _payload(args: argparse.Namespace) -> int:
    import numpy as np

    from bench.metrology import leg_error_summary
    from bench.metrology.formatting import format_length
    from bench.metrology.tables import numeric_columns, read_table_csv

    table = numeric_columns(read_table_csv(args.file), ["load_kg", "error_mm"])
    if "leg" not in table.columns:
        raise ConfigError(f"{args.file}: missing column leg")
    legs = table["leg"].astype(str).str.strip()
    # sorted by load and leg: the table's row order carries no meaning (a tie in the maximum names the lowest load)
    wide = table.assign(leg=legs).pivot_table(
        index="load_kg", columns="leg", values="error_mm", aggfunc="mean", sort=True
    )
    if wide.isna().any().any():
        raise ConfigError(f"{args.file}: some load has no error for some leg, expected every leg at every load")
    s = leg_error_summary(wide.index.to_numpy(), wide.to_numpy())
    names = [str(c) for c in wide.columns]
    # the worst error of a leg is its largest |e|, shown with its sign (a signed table's max can be a tiny positive
    # error while the leg's real worst is a large negative one); the first load wins a tie
    errors = wide.to_numpy()
    at_worst = np.argmax(np.abs(errors), axis=0)
    worst = [float(errors[i, j]) for j, i in enumerate(at_worst)]
    worst_load = [float(wide.index[i]) for i in at_worst]
    result = {
        "legs": {
            n: {
                "worst_error_mm": w,
                "load_at_worst_kg": wl,
                "max_error_mm": m,
                "load_at_max_kg": l,
                "mean_error_mm": a,
                "correlation_with_load": c,
            }
            for n, w, wl, m, l, a, c in zip(
                names, worst, worst_load, s.max_error_mm, s.load_at_max_kg, s.mean_error_mm, s.correlation_with_load
            )
        },
        "overall_mean_mm": s.overall_mean_mm,
        "overall_sd_mm": s.overall_sd_mm,
        "n_loads": s.n_loads,
    }
    lines = [f"{'leg':<5} {'worst_mm':>8} {'at_kg':>7} {'mean_mm':>8} {'r(load)':>8}  (worst: largest |e|, signed)"]
    lines += [
        f"{n:<5} {format_length(w, signed=True):>8} {wl:7.2f} {format_length(a, signed=True):>8} "
        f"{('n/a' if c is None else f'{c:+.3f}'):>8}"
        for n, w, wl, a, c in zip(names, worst, worst_load, s.mean_error_mm, s.correlation_with_load)
    ]
    lines.append(
        f"all legs: mean {format_length(s.overall_mean_mm)} mm, SD {format_length(s.overall_sd_mm)} mm over {s.n_loads} loads"
    )
    emit(result, args.json, lines)
    return 0


def _grid_positioning(args: argparse.Namespace) -> int:
    from bench.metrology.partial_pose import (
        AXIS_NAMES,
        analyze_grid_positioning,
        axis_json,
        grid_pose_json,
        grid_positioning_table,
        pooled_axis_errors,
        rate_text,
    )
    from bench.metrology.tables import read_table_csv

    table = grid_positioning_table(read_table_csv(args.file))
    results = analyze_grid_positioning(table, k=args.k)
    pooled = pooled_axis_errors(table)
    result = {
        "k": args.k,
        "poses": {r.pose: grid_pose_json(r) for r in results},
        "all_poses": {"axes": {name: axis_json(a) for name, a in zip(AXIS_NAMES, pooled)}},
    }
    lines = [
        f"{'pose':<8} {'n':>3}  {'horizontal valid (lit)':<36} {'vertical valid (lit)':<36} "
        f"{'complete':>8} {'AP_mm':>7} {'RP_mm':>7}"
    ]
    for r in results:
        s = r.statistics
        screens = [f"{rate_text(r.valid[name])} ({r.lit[name].k})" for name in ("horizontal", "vertical")]
        lines.append(
            f"{r.pose:<8} {s.n_readings:>3}  {screens[0]:<36} {screens[1]:<36} {s.n_complete:>8} "
            f"{_number(s.ap_mm):>7} {_number(s.rp_mm):>7}"
        )
        lines += [f"{'':<8} {name}: {_axis_text(a)}" for name, a in zip(AXIS_NAMES, s.axes)]
    lines.append("all poses: " + "; ".join(f"{name}: {_axis_text(a)}" for name, a in zip(AXIS_NAMES, pooled)))
    lines.append(
        f"valid = the screen decoded ok (its axes stored); lit = any sensor reported; [Wilson, z = "
        f"{args.k:g}]. Each axis counts only the readings that measured it (n); AP = mean error, 3S per axis "
        "(not ISO RP); spatial AP/RP over complete readings only. Figures are conditional on detection."
    )
    emit(result, args.json, lines)
    return 0


def _number(value: float | None, fmt: str = ".3f") -> str:
    return "-" if value is None else format(value, fmt)


def _axis_text(axis) -> str:
    if axis.n == 0:
        return "no valid reading (n 0)"
    return (
        f"n {axis.n:>2}  AP {axis.ap_mm:+.3f}  3S {_number(axis.spread_3s_mm)}  max|e| {axis.max_abs_error_mm:.3f}"
        f"  mean|e| {axis.mean_abs_error_mm:.3f} mm"
    )
