"""``bench analyze actuator`` and ``bench analyze payload``: actuator repeatability and accuracy (Groover, ISO 230-2
unidirectional) from an actuator_travel export, and leg actuation error against load."""

from __future__ import annotations

import argparse

from bench.commands.kin import emit
from bench.commands.lazy import defer
from bench.errors import ConfigError


def register(actions: argparse._SubParsersAction, new_parser) -> None:
    """Add ``actuator`` and ``payload`` to ``bench analyze`` (``new_parser`` adds FILE.csv and --json)."""
    actuator = new_parser(
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

    payload = new_parser(actions, "payload", "leg actuation error against load (project payload error)")
    payload.set_defaults(handler=_payload)


def _add_actuator_robot(parser: argparse.ArgumentParser) -> None:
    from bench.metrology.actuator_tables import ACTUATOR_ROBOTS

    parser.add_argument(
        "--robot",
        choices=ACTUATOR_ROBOTS,
        default=None,
        help="control resolution per actuator number from this robot's model (an "
        "actuator_accuracy export: --robot pkm5)",
    )


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
    from bench.metrology.formatting import format_uncertainty, format_value, reading_step_mm
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
            f"{'actuator':<9} {'n':>3} {'repeat_mm':>9} {'accuracy_mm':>11} {'U_repeat':>8} {'U_accuracy':>10} "
            f"{'max|bias|_mm':>12} {'R230_mm':>8} "
            f"{'E230_mm':>8} {'A230_mm':>8}  mean deviation per target (mm)"
        )
    ]
    step = reading_step_mm(frame["travel_mm"]) if "travel_mm" in frame else None

    def mm(value: float, u: float | None = None, signed: bool = False) -> str:
        """By its U when it has one, else never finer than the readings (as the report: figure_decimals)."""
        return format_value(value, u, signed=signed, resolution=None if u is not None else step)

    def expanded(u: float | None) -> str:
        """A U as the pose table prints its U columns (two significant digits); "—" where there is none."""
        return "—" if u is None else format_uncertainty(u)

    for r in results:
        g, iso = r.groover, r.iso230_2
        repeat_u, accuracy_u = (
            None if m is None else m.expanded_uncertainty for m in (r.repeatability_u, r.accuracy_u)
        )
        lines.append(
            f"{r.actuator:<9} {g.n:>3} {mm(g.repeatability_mm, repeat_u):>9} "
            f"{mm(g.accuracy_mm, accuracy_u):>11} {expanded(repeat_u):>8} {expanded(accuracy_u):>10} "
            f"{mm(g.max_abs_bias_mm):>12} "
            f"{mm(iso.repeatability_forward_mm):>8} {mm(iso.systematic_forward_mm):>8} {mm(iso.accuracy_forward_mm):>8}  "
            + " ".join(mm(v, u.expanded_uncertainty, True) for v, u in zip(g.mean_deviation_mm, r.bias_u))
            + (f"  ({r.dropped} readings of incomplete repeats left out)" if r.dropped else "")
        )
    lines.append(
        "Repeatability = 3 σ̄, accuracy = CR/2 + 3 σ̄ (dissertation Eqs. 8.2-8.3); bias = x̄ - target; "
        "R/E/A: ISO 230-2 unidirectional (approach from below); U_repeat, U_accuracy: their U (k as --k); figures "
        "with a U rounded by it (--json: U, full precision)."
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
