"""``bench analyze mouse``: an optical mouse's resolution, by the dissertation's per-distance method (App. A.7) or
as the 2x2 matrix fitted with an intercept per move direction (sensors.md §5.2), from a table or a
mouse_calibration run's export; every figure with a U rounded by it (GUM 7.2.6)."""

from __future__ import annotations

import argparse

from bench.commands.kin import emit
from bench.errors import ConfigError


def register(actions: argparse._SubParsersAction, new_parser) -> None:
    """Add ``mouse`` to ``bench analyze`` (``new_parser`` adds FILE.csv and --json)."""
    mouse = new_parser(
        actions,
        "mouse",
        "mouse resolution: per-distance (reading, distance_mm, position; reading "
        "numbers the readings in the order taken; N/A = restart), "
        "2x2 fit (ref_x_mm, ref_y_mm, counts_x, counts_y; optional start_reading, end_reading: the "
        "number of each move's readings, moves sharing a reading name it alike), or a mouse_calibration "
        "run's export (bench export RUN --kind mouse)",
    )
    mouse.add_argument(
        "--reference",
        metavar="REF.csv",
        default=None,
        help="a calliper-referenced run's readings (bench export RUN --kind mouse_reference)",
    )
    mouse.set_defaults(handler=_mouse)


def _mouse(args: argparse.Namespace) -> int:
    import numpy as np

    from bench.metrology import increment_resolution, increments_from_positions
    from bench.metrology.tables import numeric_columns, read_table_csv

    frame = read_table_csv(args.file)
    if {"ref_x_mm", "ref_y_mm", "counts_x", "counts_y"} <= set(frame.columns):
        numbered = {"start_reading", "end_reading"} <= set(frame.columns)
        chain = ["start_reading", "end_reading"] if numbered else []
        table = numeric_columns(frame, ["ref_x_mm", "ref_y_mm", "counts_x", "counts_y", *chain])
        return _mouse_matrix(
            args,
            table[["ref_x_mm", "ref_y_mm"]].to_numpy(),
            table[["counts_x", "counts_y"]].to_numpy(),
            _reading_numbers(args.file, table, chain),
            "the table's ref_x_mm, ref_y_mm columns",
        )
    if _RUN_EXPORT <= set(frame.columns):
        return _mouse_matrix(args, *_run_export_moves(args, frame), _run_export_reference(args))
    if not {"distance_mm", "position"} <= set(frame.columns):
        raise ConfigError(
            f"{args.file}: expected columns distance_mm, position (per-distance method) or "
            f"ref_x_mm, ref_y_mm, counts_x, counts_y (2x2 fit); found {', '.join(frame.columns)}"
        )
    if "reading" not in frame.columns:  # the increments are differences of consecutive readings
        raise ConfigError(
            f"{args.file}: missing column reading, expected the number of each position reading in the "
            f"order taken (row order carries no meaning)"
        )
    restart = frame["position"].str.strip().str.upper().isin(["N/A", "NA", ""])
    table = numeric_columns(
        frame.assign(position=frame["position"].where(~restart, "0")), ["reading", "distance_mm", "position"]
    )
    table.loc[restart, "position"] = np.nan  # a restart marker breaks the segment; it is never a zero
    repeated = table["reading"].duplicated()
    if repeated.any():
        index = repeated.idxmax()
        raise ConfigError(
            f"{args.file}: row {int(index) + 1}, column reading: {table.at[index, 'reading']:g} repeated, "
            f"expected one row per reading"
        )
    table = table.sort_values("reading", kind="stable")
    header = f"{'distance_mm':>11} {'n':>4} {'mean_delta':>10} {'mm_per_count':>12} {'3sigma':>7} {'tolerance_mm':>12}"
    result, lines = {}, [header]
    for distance, rows in table.groupby("distance_mm", sort=True):
        r = increment_resolution(distance, increments_from_positions(rows["position"].to_numpy()))
        result[f"{distance:g}"] = {
            "n": r.n,
            "mean_delta_counts": r.mean_delta_counts,
            "resolution_mm_per_count": r.resolution_mm_per_count,
            "three_sigma_counts": r.three_sigma_counts,
            "tolerance_mm": r.tolerance_mm,
        }
        lines.append(
            f"{distance:11g} {r.n:4d} {r.mean_delta_counts:10.3f} {r.resolution_mm_per_count:12.5f} "
            f"{r.three_sigma_counts:7.3f} {r.tolerance_mm:12.4f}"
        )
    lines.append("Resolution = distance / mean Δ; tolerance = 3 S(Δ) x resolution (dissertation App. A.7).")
    emit({"method": "increments", "distances": result}, args.json, lines)
    return 0


#: The columns of a mouse_calibration run's ``mouse`` export that the 2x2 fit reads.
_RUN_EXPORT = {"pose", "cycle", "step_index", "cmd_x_mm", "cmd_y_mm", "mouse_xy_x_counts", "mouse_xy_y_counts"}


def _run_export_moves(args: argparse.Namespace, frame):
    """The moves of a mouse_calibration run's export, as the run's own fit pairs them
    (:func:`bench.protocols.dissertation.mouse_calibration_moves`): against the calliper readings of ``--reference``
    when given, else the commanded travel."""
    from types import SimpleNamespace

    from bench.metrology.tables import numeric_columns, read_table_csv
    from bench.protocols.dissertation import mouse_calibration_moves

    numbers = numeric_columns(frame, sorted(_RUN_EXPORT - {"pose"})).sort_values("step_index", kind="stable")
    rows = [
        SimpleNamespace(pose=str(row["pose"]), cycle=int(row["cycle"]), values=row) for _, row in numbers.iterrows()
    ]
    references = None
    if args.reference is not None:
        readings = read_table_csv(args.reference)
        if not {"pose", "cycle", "reference_mm"} <= set(readings.columns):
            raise ConfigError(
                f"{args.reference}: expected columns pose, cycle, reference_mm (bench export RUN "
                f"--kind mouse_reference); found {', '.join(readings.columns)}"
            )
        references = [
            SimpleNamespace(pose=str(row["pose"]), cycle=int(row["cycle"]), values=row)
            for _, row in numeric_columns(readings, ["cycle", "reference_mm"]).iterrows()
        ]
    return mouse_calibration_moves(rows, references)


def _reading_numbers(path, table, columns: list[str]):
    """Each move's start and end reading number (K, 2) from ``columns`` of a move table; without them every move
    has readings of its own (no two moves share one)."""
    import numpy as np

    if not columns:
        return np.arange(2 * len(table)).reshape(-1, 2)
    numbers = table[columns].to_numpy()
    whole = numbers == np.round(numbers)
    if not whole.all():
        row, column = np.argwhere(~whole)[0]
        raise ConfigError(
            f"{path}: row {row + 1}, column {columns[column]}: {numbers[row, column]:g}, expected a whole reading number"
        )
    return numbers.astype(int)


def _run_export_reference(args: argparse.Namespace) -> str:
    """What a run export's fit is made against, in words: the calliper readings of ``--reference``, else the
    commanded travel, with the hint a calliper-referenced run needs (a fit against the robot under test is never
    silent, issue 32)."""
    if args.reference is not None:
        return f"the calliper readings of {args.reference}"
    return (
        "the commanded travel (cmd_x_mm, cmd_y_mm), right for a calibrated-axis run; a calliper-referenced run: "
        "add --reference REF.csv (bench export RUN --kind mouse_reference)"
    )


def _mouse_matrix(args: argparse.Namespace, reference, counts, readings, reference_source: str) -> int:
    from bench.metrology import fit_matrix
    from bench.metrology.formatting import format_measured, format_uncertainty
    from bench.metrology.mouse_calibration import counts_per_inch

    # an intercept per move direction models a start/stop offset (sensors.md: without it the offset goes into A);
    # the moves' shared readings carry their quantisation and reference error into both (the weighted fit)
    fit = fit_matrix(reference, counts, per_direction=True, readings=readings)
    k = fit.coverage_factor
    intercepts = {
        label: {
            "counts": fit.offsets_counts[i].tolist(),
            "u_counts": fit.u_offsets_counts[i].tolist(),
            "significant": fit.offsets_significant[i].tolist(),
        }
        for i, label in enumerate(fit.offset_labels)
    }
    result = {
        "method": "matrix",
        "n": fit.n,
        "A_mm_per_count": fit.a_mm_per_count.tolist(),
        "u_A_mm_per_count": fit.u_a_mm_per_count.tolist(),
        "k": k,
        "U_A_mm_per_count": fit.expanded_a_mm_per_count.tolist(),
        "dof": fit.dof,
        "rotation_deg": fit.rotation_deg,
        "scale_mm_per_count": fit.scale_mm_per_count.tolist(),
        "sigma_counts": fit.sigma_counts.tolist(),
        "intercepts_by_direction": intercepts,
        "reference": reference_source,
    }
    a, big_u = fit.a_mm_per_count, fit.expanded_a_mm_per_count
    scales = [(s, k * u) for s, u in zip(fit.scale_mm_per_count, fit.u_scale_mm_per_count())]
    lines = [
        f"reference: {reference_source}",
        f"A (mm/count), n = {fit.n} moves, ± U (95 %, k = {k:.2f}, {fit.dof} dof):",
        *(
            "  [" + "  ".join(format_measured(a[i, j], big_u[i, j], signed=True) for j in range(2)) + "]"
            for i in range(2)
        ),
        (
            f"rotation {fit.rotation_deg:+.3f} deg, scale x/y (± U, the fit's only) "
            + " / ".join(
                f"{format_measured(s, u)} mm/count ({format_measured(*counts_per_inch(s, u))} cpi)" for s, u in scales
            )
            + f", residual SD {format_uncertainty(fit.sigma_counts[0])} / {format_uncertainty(fit.sigma_counts[1])} counts"
        ),
        "intercept per move direction (counts, ± U; * = significant at 95 %: a start/stop offset or lost counts):",
    ]
    for i, label in enumerate(fit.offset_labels):
        cells = [
            format_measured(fit.offsets_counts[i, j], k * fit.u_offsets_counts[i, j], signed=True)
            + f"{'*' if fit.offsets_significant[i, j] else ' '}"
            for j in range(2)
        ]
        lines.append(f"  {label}: sensor x {cells[0]}  sensor y {cells[1]}")
    emit(result, args.json, lines)
    return 0
