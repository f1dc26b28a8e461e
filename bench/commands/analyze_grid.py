"""``bench analyze grid-positioning``: a delta robot read by the laser grid: hit rates per screen, per-axis AP and
3 S over the readings that measured each axis (delta_positioning runs)."""

from __future__ import annotations

import argparse

from bench.commands.kin import emit


def register(actions: argparse._SubParsersAction, new_parser) -> None:
    """Add ``grid-positioning`` to ``bench analyze`` (``new_parser`` adds FILE.csv and --json)."""
    grid = new_parser(
        actions,
        "grid-positioning",
        "delta robot read by the laser grid: hit rate per screen and "
        "per-axis AP, 3 S, max/mean |error| over the readings that "
        "measured each axis (delta_positioning runs)",
    )
    grid.add_argument("--k", type=float, default=2.0, help="coverage factor: z of the rates' Wilson intervals")
    grid.set_defaults(handler=_grid_positioning)


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
