"""``bench analyze`` for vAP, paths, cornering, path velocity and positioning time (ISO 9283 7.2.3, 8, 9).

The tables are described in `bench.metrology.path_tables`; every handler prints a readable table or, with
``--json``, one JSON object whose keys carry their units. Numbers are rounded in the text only.
"""

from __future__ import annotations

import argparse

from bench.commands.kin import emit
from bench.errors import ConfigError


def register(actions: argparse._SubParsersAction, new_parser) -> None:
    """Add the subcommands to ``bench analyze`` (``new_parser`` adds FILE.csv and --json)."""
    vap = new_parser(
        actions,
        "vap",
        "multi-directional pose accuracy variation vAP_p, vAP_a/b/c (ISO 9283 7.2.3); "
        "pose labels name the approach: P1/+x, P1/-y, P1/+z",
    )
    vap.set_defaults(handler=_vap)

    exchange = new_parser(
        actions,
        "exchangeability",
        "exchangeability E per pose (ISO 9283 7.7): the largest "
        "distance between the barycentres of the robots (or "
        "mountings) named in the column given by --by",
    )
    exchange.add_argument("--by", default="robot", help="column naming the robot or mounting of each sample")
    exchange.set_defaults(handler=_exchangeability)

    path = new_parser(
        actions,
        "path",
        "path accuracy AT and repeatability RT (ISO 9283 8.2, 8.3; with angles also "
        "AT_a/RT_a, 8.4): FILE.csv has cycle, t_s, x_mm, y_mm[, z_mm][, a_deg..]",
    )
    path.add_argument(
        "--commanded",
        metavar="STATIONS.csv",
        required=True,
        help="the commanded path: station, x_mm, y_mm[, z_mm][, a_deg..], one row per station",
    )
    path.add_argument(
        "--instrument-u-mm",
        type=float,
        default=None,
        help="instrument standard uncertainty per axis (mm), an offset common to the run, in U(AT); without it "
        "U excludes the instrument and says so",
    )
    path.set_defaults(handler=_path)

    corner = new_parser(actions, "cornering", "cornering round-off CR and overshoot CO at one corner (ISO 9283 8.5)")
    corner.add_argument("--corner", type=_point, required=True, metavar="X,Y[,Z]", help="commanded corner (mm)")
    corner.add_argument(
        "--from",
        dest="start",
        type=_point,
        required=True,
        metavar="X,Y[,Z]",
        help="start of the commanded segment into the corner (mm); negative values as --from=-10,0",
    )
    corner.add_argument(
        "--to",
        dest="end",
        type=_point,
        required=True,
        metavar="X,Y[,Z]",
        help="end of the commanded segment out of the corner (mm)",
    )
    corner.set_defaults(handler=_cornering)

    velocity = new_parser(
        actions,
        "path-velocity",
        "path velocity accuracy AV, repeatability RV, fluctuation FV "
        "(ISO 9283 8.6) over the constant-velocity part in FILE.csv",
    )
    velocity.add_argument("--commanded-mm-s", type=float, required=True, help="commanded path velocity (mm/s)")
    velocity.add_argument(
        "--instrument-u-pct",
        type=float,
        default=None,
        help="the speed instrument's relative standard uncertainty (its scale, %%) in U(AV); without it U excludes "
        "the instrument and says so",
    )
    velocity.set_defaults(handler=_path_velocity)

    positioning = new_parser(
        actions,
        "positioning-time",
        "minimum positioning time per step (ISO 9283 9): FILE.csv has step, cycle, t_s, x_mm, y_mm[, z_mm]",
    )
    positioning.add_argument(
        "--band-mm",
        type=float,
        nargs="+",
        default=[0.1, 0.5, 1.0],
        help="limit bands B (mm); ISO comparison bands 0.1, 0.5, 1.0",
    )
    positioning.add_argument(
        "--hysteresis-mm",
        type=float,
        default=0.0,
        help="excursions up to this far beyond the band are not counted (instrument resolution)",
    )
    positioning.set_defaults(handler=_positioning)


def register_run(actions: argparse._SubParsersAction) -> None:
    """``bench analyze path-run RUN_ID``: the figures of a stored path run, from its raw streamed samples."""
    run = actions.add_parser(
        "path-run",
        help="AT/RT, CR/CO, AV/RV/FV of a stored iso9283_path or iso9283_cornering "
        "run (ISO 9283 8.2, 8.3, 8.5, 8.6), from its raw streamed samples",
        description="AT/RT (and CR/CO on the rectangle, AV/RV/FV on the line) per path and "
        "velocity of a stored path run",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    run.add_argument("run_id", metavar="RUN_ID", type=int, help="the stored path run")
    run.add_argument("--store", default="bench.db", help="run store (SQLite file)")
    run.add_argument("--json", action="store_true", help="print the result as one JSON object")
    run.set_defaults(handler=_path_run)

    positioning = actions.add_parser(
        "positioning-run",
        help="minimum positioning time per step of a stored "
        "iso9283_positioning_time run (ISO 9283 9), from its raw "
        "streamed samples",
        description="mean and largest positioning time per step, velocity, load and "
        "limit band of a stored iso9283_positioning_time run",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    positioning.add_argument("run_id", metavar="RUN_ID", type=int, help="the stored positioning-time run")
    positioning.add_argument("--store", default="bench.db", help="run store (SQLite file)")
    positioning.add_argument(
        "--band-mm",
        type=float,
        nargs="+",
        default=None,
        help="limit bands B (mm); default the ISO comparison bands 0.1, 0.5, 1.0",
    )
    positioning.add_argument(
        "--hysteresis-mm",
        type=float,
        default=None,
        help="excursions up to this far beyond the band are not counted; default one count of the run's instrument",
    )
    positioning.add_argument("--json", action="store_true", help="print the result as one JSON object")
    positioning.set_defaults(handler=_positioning_run)


def _path_run(args: argparse.Namespace) -> int:

    from bench.reports.path import REORIENTATION_NOT_MEASURED
    from bench.reports.path_run import analyze_path_run, figure_text
    from bench.store import Store

    store = Store(args.store, read_only=True)
    try:
        result = analyze_path_run(store, args.run_id)
    finally:
        store.close()
    lines = [
        f"{'path':<10} {'v_pct':>5} {'v_c_mm_s':>8} {'n':>3} {'AT_mm':>15} {'RT_mm':>15} {'CR_mm':>7} "
        f"{'CO_mm':>7} {'AV_pct':>13} {'RV_pct':>13} {'FV_mm_s':>8}"
    ]
    for f in result.figures:
        j = f.as_json()

        def cell(key: str, fmt: str, j: dict = j) -> str:
            return format(j[key], fmt) if key in j else "-"

        lines.append(
            f"{f.shape:<10} {f.velocity_pct:>5g} {f.commanded_mm_s:>8.3f} {f.n_cycles:>3} "
            f"{figure_text(f.at_mm, f.at_u):>15} {figure_text(f.rt_mm, f.rt_u):>15} {cell('CR_mm', '7.3f'):>7} "
            f"{cell('CO_mm', '7.3f'):>7} {figure_text(f.av_pct, f.av_u, signed=True, none='-'):>13} "
            f"{figure_text(f.rv_pct, f.rv_u, none='-'):>13} {cell('FV_mm_s', '8.3f'):>8}"
        )
    lines.append(f"U with k = 2, values rounded by their U; {result.budget}; {result.speed_budget}.")
    lines.append(f"8.4: {REORIENTATION_NOT_MEASURED}.")
    emit(
        {
            "run_id": args.run_id,
            "protocol": result.protocol_name,
            "rated_path_velocity_mm_s": result.design.rated_mm_s,
            "paths": [f.as_json() for f in result.figures],
            "not_measured": {"8.4": REORIENTATION_NOT_MEASURED},
        },
        args.json,
        lines,
    )
    return 0


def _positioning_run(args: argparse.Namespace) -> int:

    from bench.reports.positioning_time import analyze_positioning_run
    from bench.store import Store

    store = Store(args.store, read_only=True)
    try:
        result = analyze_positioning_run(store, args.run_id, bands_mm=args.band_mm, hysteresis_mm=args.hysteresis_mm)
    finally:
        store.close()
    lines = [
        f"{'v_pct':>5} {'load_kg':>7} {'band_mm':>7} {'step':>4} {'distance_mm':>11} {'mean_t_s':>8} {'max_t_s':>8}"
    ]
    for f in result.figures:
        if f.result is None:
            lines.append(f"{f.velocity_pct:>5g} {f.load_kg:>7g} {f.band_mm:>7g}  no figure: {f.reason}")
            continue
        r = f.result
        lines += [
            f"{f.velocity_pct:>5g} {f.load_kg:>7g} {f.band_mm:>7g} {s:>4} {d:>11.3f} {mean:>8.3f} {worst:>8.3f}"
            for s, d, mean, worst in zip(f.steps, r.step_distance_mm, r.mean_time_s, r.max_time_s)
        ]
    lines += [
        f"step {s['step']} skipped: target ({', '.join(f'{v:g}' for v in s['target_mm'])}) mm outside the workspace"
        for s in result.skipped
    ]
    lines.append(f"hysteresis h = {result.hysteresis_mm:g} mm ({result.hysteresis_source})")
    emit(result.as_json(), args.json, lines)
    return 0


def _point(text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) not in (2, 3):
        raise argparse.ArgumentTypeError(f"{text!r}: expected 2 or 3 comma-separated numbers in mm, e.g. 0,10,5")
    return values


def _vap(args: argparse.Namespace) -> int:
    from bench.metrology.path_tables import analyze_multidirectional
    from bench.metrology.tables import POSE_NUMERIC_COLUMNS, pose_table, read_table_csv

    table = pose_table(read_table_csv(args.file, numeric=POSE_NUMERIC_COLUMNS))
    if table.empty:
        raise ConfigError(f"{args.file}: no rows, expected the poses of a multi-directional test")
    results = analyze_multidirectional(table)
    poses, lines = {}, [f"{'pose':<12} {'directions':<24} {'n':>9} {'vAP_p_mm':>9}  orientation"]
    for r in results:
        entry = poses[r.label] = {
            "directions": list(r.directions),
            "n_per_direction": list(r.n_per_direction),
            "vAP_p_mm": r.position.vap_mm,
            "farthest_pair": [r.directions[i] for i in r.position.farthest_pair],
        }
        angles = ""
        if r.orientation is not None:
            entry.update({f"vAP_{name}_deg": v for name, v in zip(r.angle_names, r.orientation.vap_deg)})
            angles = ", ".join(f"vAP_{name} {v:.3f} deg" for name, v in zip(r.angle_names, r.orientation.vap_deg))
        lines.append(
            f"{r.label:<12} {', '.join(d.split('/', 1)[-1] for d in r.directions):<24} "
            f"{'/'.join(map(str, r.n_per_direction)):>9} {r.position.vap_mm:>9.4f}  {angles}"
        )
    lines.append("vAP_p: largest distance between the barycentres of the approach directions.")
    emit({"poses": poses}, args.json, lines)
    return 0


def _exchangeability(args: argparse.Namespace) -> int:
    from bench.metrology import exchangeability
    from bench.metrology.tables import POSE_NUMERIC_COLUMNS, condition_groups, pose_table, read_table_csv

    table = pose_table(read_table_csv(args.file, numeric=POSE_NUMERIC_COLUMNS))
    if args.by not in table.columns:
        raise ConfigError(f"{args.file}: missing column {args.by}, expected the robot or mounting of each sample")
    table[args.by] = table[args.by].astype(str).str.strip()
    poses, lines = {}, [f"{'pose':<12} {'robots':>6} {'E_mm':>9}  farthest pair"]
    for label, _, _, rows in condition_groups(table):
        names = tuple(sorted(rows[args.by].unique()))
        r = exchangeability([rows[rows[args.by] == n][["x_mm", "y_mm", "z_mm"]].to_numpy() for n in names])
        pair = [names[i] for i in r.farthest_pair]
        poses[label] = {args.by: list(names), "E_mm": r.vap_mm, "farthest_pair": pair}
        lines.append(f"{label:<12} {len(names):>6} {r.vap_mm:>9.4f}  {' / '.join(pair)}")
    emit({"poses": poses}, args.json, lines)
    return 0


def _path(args: argparse.Namespace) -> int:
    from bench.metrology import path_characteristics, path_orientation_characteristics
    from bench.metrology.formatting import format_length
    from bench.metrology.iso9283_dynamics import station_crossings
    from bench.metrology.path_tables import path_cycles, path_table, station_table
    from bench.metrology.tables import read_table_csv
    from bench.metrology.uncertainty import instrument_budget
    from bench.metrology.uncertainty_figures import PATH_U_MIN_CYCLES, path_uncertainty

    table = path_table(read_table_csv(args.file))
    cycles = path_cycles(table)
    stations, commanded_deg, angle_columns = station_table(read_table_csv(args.commanded))
    paths = [c.position_mm for c in cycles]
    attained_columns = tuple(c for c in ("a_deg", "b_deg", "c_deg") if c in table.columns)
    if attained_columns != angle_columns:
        raise ConfigError(
            f"{args.file} has angle columns ({', '.join(attained_columns) or 'none'}) and "
            f"{args.commanded} ({', '.join(angle_columns) or 'none'}), expected the same"
        )
    r = path_characteristics(paths, stations)
    budget = instrument_budget(args.instrument_u_mm, "--instrument-u-mm")
    result = {
        "n_cycles": r.n_cycles,
        "n_stations": len(stations),
        "AT_mm": r.at_mm,
        "RT_mm": r.rt_mm,
        "U_AT_mm": None,
        "U_RT_mm": None,
        "k": 2.0,
        "U_budget": budget,
        "AT_per_station_mm": r.at_per_station_mm.tolist(),
        "RT_per_station_mm": r.rt_per_station_mm.tolist(),
    }
    lines = [
        f"{r.n_cycles} cycles, {len(stations)} stations "
        f"(worst station {int(r.at_per_station_mm.argmax()) + 1} / {int(r.rt_per_station_mm.argmax()) + 1})"
    ]
    if r.n_cycles >= PATH_U_MIN_CYCLES:  # the path model needs a scatter over at least 3 cycles
        crossings = station_crossings(paths, stations)[0]
        u = path_uncertainty(crossings, stations, instrument_u_mm=args.instrument_u_mm or 0.0)
        result["U_AT_mm"], result["U_RT_mm"] = u.at.expanded_uncertainty, u.rt.expanded_uncertainty
        lines.append(f"AT_p = {u.at}, RT_p = {u.rt} (path-model Monte Carlo, values rounded by their U); {budget}")
    else:
        lines.append(
            f"AT_p = {format_length(r.at_mm)} mm, RT_p = {format_length(r.rt_mm)} mm; no U: {r.n_cycles} cycles, "
            f"at least {PATH_U_MIN_CYCLES} needed"
        )
    if angle_columns:
        o = path_orientation_characteristics(paths, [c.angles_deg for c in cycles], stations, commanded_deg)
        for column, at, rt in zip(angle_columns, o.at_deg, o.rt_deg):
            name = column[0]
            result[f"AT_{name}_deg"], result[f"RT_{name}_deg"] = at, rt
            lines.append(f"AT_{name} = {format_length(at)} deg, RT_{name} = ±{format_length(rt)} deg")
    emit(result, args.json, lines)
    return 0


def _cornering(args: argparse.Namespace) -> int:
    from bench.metrology import cornering_deviations
    from bench.metrology.formatting import format_length
    from bench.metrology.path_tables import path_cycles, path_table
    from bench.metrology.tables import read_table_csv

    cycles = path_cycles(path_table(read_table_csv(args.file)))
    d = cycles[0].position_mm.shape[1]
    for option, point in (("--corner", args.corner), ("--from", args.start), ("--to", args.end)):
        if len(point) != d:
            raise ConfigError(
                f"{option} {','.join(f'{v:g}' for v in point)}: {len(point)} coordinates, expected {d} like the table"
            )
    r = cornering_deviations([c.position_mm for c in cycles], args.corner, args.start, args.end)
    result = {
        "n": r.n,
        "CR_mm": r.cr_mm,
        "CO_mm": r.co_mm,
        "mean_CR_mm": r.mean_cr_mm,
        "mean_CO_mm": r.mean_co_mm,
        "cycles": [
            {"cycle": c.cycle, "CR_mm": cr, "CO_mm": co}
            for c, cr, co in zip(cycles, r.cr_per_cycle_mm, r.co_per_cycle_mm)
        ],
    }
    lines = [
        f"{r.n} cycles: CR = {format_length(r.cr_mm)} mm (mean {format_length(r.mean_cr_mm)}), "
        f"CO = {format_length(r.co_mm)} mm (mean {format_length(r.mean_co_mm)}); worst cycle shown"
    ]
    lines += [
        f"  cycle {c.cycle:>3}: CR = {format_length(cr)} mm, CO = {format_length(co)} mm"
        for c, cr, co in zip(cycles, r.cr_per_cycle_mm, r.co_per_cycle_mm)
    ]
    emit(result, args.json, lines)
    return 0


def _path_velocity(args: argparse.Namespace) -> int:
    from bench.metrology import path_speed, path_velocity_characteristics
    from bench.metrology.formatting import format_measured
    from bench.metrology.path_tables import path_cycles, path_table
    from bench.metrology.tables import read_table_csv
    from bench.metrology.uncertainty import speed_instrument_budget
    from bench.metrology.uncertainty_figures import mean_speed_uncertainty, spread_uncertainty

    cycles = path_cycles(path_table(read_table_csv(args.file)))
    r = path_velocity_characteristics([path_speed(c.t_s, c.position_mm) for c in cycles], args.commanded_mm_s)
    declared = args.instrument_u_pct
    if declared is not None and not declared >= 0:
        raise ConfigError(f"--instrument-u-pct = {declared}, expected a number >= 0")
    u_av = mean_speed_uncertainty(
        r.av_pct, r.mean_speed_per_cycle_mm_s, r.commanded_mm_s, instrument_u_pct=declared or 0.0
    )
    u_rv = spread_uncertainty(r.rv_pct, r.n, unit="%")
    budget = speed_instrument_budget(declared, "--instrument-u-pct")
    result = {
        "n": r.n,
        "commanded_mm_s": r.commanded_mm_s,
        "mean_speed_mm_s": r.mean_speed_mm_s,
        "AV_pct": r.av_pct,
        "RV_pct": r.rv_pct,
        "FV_mm_s": r.fv_mm_s,
        "U_AV_pct": u_av.expanded_uncertainty,
        "k_AV": u_av.coverage_factor,
        "U_RV_pct": u_rv.expanded_uncertainty,
        "U_budget": budget,
        "mean_speed_per_cycle_mm_s": list(r.mean_speed_per_cycle_mm_s),
    }
    lines = [
        f"{r.n} cycles at v_c = {r.commanded_mm_s:g} mm/s: mean {r.mean_speed_mm_s:.3f} mm/s, "
        f"FV = {r.fv_mm_s:.3f} mm/s",
        f"AV = {format_measured(r.av_pct, u_av.expanded_uncertainty, signed=True)} % "
        f"(k = {u_av.coverage_factor:.2f}), RV = {format_measured(r.rv_pct, u_rv.expanded_uncertainty)} % (k = 2), "
        f"values rounded by their U; {budget}",
    ]
    emit(result, args.json, lines)
    return 0


def _positioning(args: argparse.Namespace) -> int:
    from bench.metrology import minimum_positioning_time
    from bench.metrology.path_tables import positioning_steps
    from bench.metrology.tables import read_table_csv

    for band in args.band_mm:
        if not band > 0:
            raise ConfigError(f"--band-mm {band:g}: expected limit bands > 0 mm")
    numbers, steps = positioning_steps(read_table_csv(args.file))
    result: dict = {"hysteresis_mm": args.hysteresis_mm, "bands": {}}
    lines = [f"{'band_mm':>7} {'step':>4} {'distance_mm':>11} {'mean_t_s':>8} {'max_t_s':>8}"]
    for band in args.band_mm:
        r = minimum_positioning_time(steps, band_mm=band, hysteresis_mm=args.hysteresis_mm)
        result["bands"][f"{band:g}"] = [
            {"step": s, "distance_mm": dist, "mean_time_s": mean, "max_time_s": worst, "time_s_per_cycle": list(per)}
            for s, dist, mean, worst, per in zip(
                numbers, r.step_distance_mm, r.mean_time_s, r.max_time_s, r.time_s_per_cycle
            )
        ]
        lines += [
            f"{band:>7g} {s:>4} {dist:>11.3f} {mean:>8.3f} {worst:>8.3f}"
            for s, dist, mean, worst in zip(numbers, r.step_distance_mm, r.mean_time_s, r.max_time_s)
        ]
    emit(result, args.json, lines)
    return 0
