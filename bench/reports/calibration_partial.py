"""The gain of a kinematic calibration seen by an instrument with partial readings (the laser grid).

Two laser-grid runs (``bench report AFTER --compare BEFORE``) have, per pose, the statistics of
:func:`bench.metrology.partial_pose.partial_pose_statistics`: per axis over the readings that measured it, spatial AP
and RP over the complete readings. The gain compares like with like only:

* mean |AP_x| (likewise y, z) = (1/n) sum_j |x̄_j - x_cj| over the n poses where both runs measured x at least once
  (ISO 9283 7.2.1 on one axis, each run over its own readings of the axis);
* mean AP_P over the poses with at least one complete reading in both runs, mean RP_l over those with at least two
  (ISO 9283 7.2.1 / 7.2.2 over the complete readings);
* the readings with all three axes, before and after: the detection the figures are conditional on.

Each row states its n; a row without a pose measured in both runs prints "no pose measured in both" and no factor.
The laser grid quantises every reading to its 2.5 mm lattice within ±r (docs/sensors.md), so a factor from it
is bounded by that, not by the calibration.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from bench.metrology.partial_pose import AXIS_NAMES, NO_READING
from bench.reports.document import Paragraph, Table, fmt_mm

__all__ = ["partial_blocks", "partial_gain_rows"]

NONE_IN_BOTH = "no pose measured in both"


def _paired(pair) -> list[tuple[Any, Any]]:
    after = {p.pose: p for p in pair.after.poses}
    return [(p, after[p.pose]) for p in pair.before.poses if p.pose in after]


def _row(name: str, values: list[tuple[float, float]]) -> tuple[str, str, str, str]:
    if not values:
        return (f"{name} (n = 0)", NONE_IN_BOTH, NONE_IN_BOTH, "—")
    before, after = np.asarray(values, dtype=float).mean(axis=0)
    return (
        f"{name} (n = {len(values)} pose{'' if len(values) == 1 else 's'})",
        fmt_mm(before),
        fmt_mm(after),
        f"{before / after:.1f}" if after > 0 else "—",
    )


def partial_gain_rows(pair) -> tuple[tuple[str, str, str, str], ...]:
    """The gain table's rows: quantity (with its n of poses), before (mm), after (mm), factor (module docstring)."""
    paired = _paired(pair)
    rows = [
        _row(
            "mean AP_P, complete readings",
            [
                (b.statistics.ap_mm, a.statistics.ap_mm)
                for b, a in paired
                if b.statistics.ap_mm is not None and a.statistics.ap_mm is not None
            ],
        )
    ]
    for k, name in enumerate(AXIS_NAMES):
        rows.append(
            _row(
                f"mean |AP_{name}|, readings that measured {name}",
                [
                    (abs(b.statistics.axes[k].ap_mm), abs(a.statistics.axes[k].ap_mm))
                    for b, a in paired
                    if b.statistics.axes[k].n and a.statistics.axes[k].n
                ],
            )
        )
    rows.append(
        _row(
            "mean RP_l, complete readings",
            [
                (b.statistics.rp_mm, a.statistics.rp_mm)
                for b, a in paired
                if b.statistics.rp_mm is not None and a.statistics.rp_mm is not None
            ],
        )
    )
    complete = [sum(p.statistics.n_complete for p in run) for run in zip(*paired)] if paired else [0, 0]
    readings = [sum(p.statistics.n_readings for p in run) for run in zip(*paired)] if paired else [0, 0]
    rows.append(
        ("readings with x, y and z (complete)", f"{complete[0]} / {readings[0]}", f"{complete[1]} / {readings[1]}", "—")
    )
    return tuple(rows)


def _cell(value: float | None, n: int) -> str:
    return NO_READING if n == 0 or value is None else f"{value:+.4f}"


def _pose_rows(pair) -> tuple[tuple[str, ...], ...]:
    rows = []
    for b, a in _paired(pair):
        cells = [b.pose]
        for run in (b, a):
            s = run.statistics
            cells.append("—" if s.ap_mm is None else fmt_mm(s.ap_mm))
        for k in range(3):
            cells += [_cell(run.statistics.axes[k].ap_mm, run.statistics.axes[k].n) for run in (b, a)]
        cells += [f"{run.statistics.n_complete} / {run.statistics.n_readings}" for run in (b, a)]
        rows.append(tuple(cells))
    return tuple(rows)


def partial_blocks(pair, name: Callable[[Any], str]) -> list:
    """The gain paragraph and tables of two laser-grid runs (``name``: a calibration record's printed name)."""
    before, after, record = pair.before, pair.after, pair.after_calibration
    rows = partial_gain_rows(pair)
    return [
        Paragraph(
            f"Before: run {before.run.id}, {name(pair.before_calibration)} in force. After: run "
            f"{after.run.id}, {name(record)} in force (identified from run {record.source_run_id}). Both runs "
            "were read by the laser grid, whose readings are partial: each figure is over the readings that "
            "measured it (its n of poses in the first column), never a filled axis, and is conditional on "
            "detection. Over those poses the mean AP_P (complete readings) goes from "
            f"{rows[0][1]} mm to {rows[0][2]} mm (factor {rows[0][3]})."
        ),
        Table(
            "calibration-gain",
            ("Quantity (over the poses measured in both runs)", "Before (mm)", "After (mm)", "Factor before / after"),
            rows,
            f"Gain of the calibration seen by the laser grid: run {before.run.id} (before) against run "
            f"{after.run.id} (after); readings quantised to the grid's lattice within ±r",
        ),
        Table(
            "calibration-poses",
            (
                "Pose",
                "AP_P before (mm)",
                "AP_P after (mm)",
                "AP_x before",
                "AP_x after",
                "AP_y before",
                "AP_y after",
                "AP_z before",
                "AP_z after",
                "Complete before",
                "Complete after",
            ),
            _pose_rows(pair),
            f"Per pose, before and after: AP_P over the complete readings (—: none), the signed per-axis AP over "
            f"the readings that measured the axis ({NO_READING}: none), mm",
        ),
    ]
