"""Pose statistics from partial readings: instruments that measure some axes of a reading and not others.

The delta robot's laser grid (delta4-lasergrid.md §4) measures x, y on its horizontal screen and y, z on its
vertical screen, each only when the screen decodes (a blind 2.5 mm phase, a beam off the array, an ambiguous laser
or a fault measure nothing). A reading is then a row of (x, y, z) in mm with NaN where the axis was not measured.
These functions never fill a missing axis: each axis is summarised over the readings that measured it, with its own
n, and a statistic that needs more readings than there are is ``None``, never 0 or NaN.

- Per axis (readings that measured the axis): AP component x̄ - x_c (ISO 9283 7.2.1, one axis), 3 S (the per-axis
  spread of :func:`bench.metrology.iso9283.pose_repeatability`, not an ISO RP), and the delta thesis's own figures
  (§8.4.2): the maximum and the mean of |x_j - x_c|.
- Spatial AP and RP_l (ISO 9283 7.2.1-7.2.2) from the complete readings only (all three axes in the same reading).
- Detection rates k/n with a Wilson score interval at z = the coverage factor k (2 by default), printed by
  :func:`rate_text`.

A statistic over the readings that measured an axis is conditional on detection: when detection depends on where
the pose lies (the grid detects only within the window r of its 2.5 mm lattice points), the detected readings are
not a random sample of the pose's scatter. Report the detection rate beside every figure.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from bench.errors import ConfigError
from bench.metrology.iso9283 import pose_accuracy, pose_repeatability

if TYPE_CHECKING:
    import pandas as pd

__all__ = [
    "AXIS_NAMES",
    "GRID_COLUMNS",
    "NO_READING",
    "AxisErrors",
    "DetectionRate",
    "GridPoseResult",
    "PartialPoseStatistics",
    "analyze_grid_positioning",
    "axis_errors",
    "axis_json",
    "detection_rate",
    "grid_pose_json",
    "grid_positioning_table",
    "partial_pose_statistics",
    "pooled_axis_errors",
    "rate_text",
]

AXIS_NAMES = ("x", "y", "z")
#: What a rate (or an axis) without a single reading prints: never 0.
NO_READING = "no reading"


@dataclass(frozen=True)
class AxisErrors:
    """One axis of one pose over the readings that measured it (``None``: not enough readings)."""

    n: int  #: readings that measured this axis
    ap_mm: float | None  #: signed x̄ - x_c (n >= 1)
    spread_3s_mm: float | None  #: 3 S, S with n - 1 (n >= 2); not an ISO RP
    max_abs_error_mm: float | None  #: max |x_j - x_c| (the thesis's axial accuracy, §8.4.2)
    mean_abs_error_mm: float | None  #: mean |x_j - x_c| (the thesis's mean axial error)


@dataclass(frozen=True)
class PartialPoseStatistics:
    """Per-axis and spatial statistics of one command pose."""

    n_readings: int  #: readings taken, measured or not
    axes: tuple[AxisErrors, ...]  #: x, y, z
    n_complete: int  #: readings with every axis measured
    ap_mm: float | None  #: spatial AP_P over the complete readings (n_complete >= 1)
    rp_mm: float | None  #: RP_l = l̄ + 3 S_l over the complete readings (n_complete >= 2)


@dataclass(frozen=True)
class DetectionRate:
    """k detections in n readings, with the Wilson score interval at z = k (coverage factor, 2: about 95 %)."""

    k: int
    n: int
    rate: float | None  #: k / n (None when n = 0)
    low: float | None
    high: float | None


def axis_errors(measured_mm: ArrayLike, commanded_mm: float) -> AxisErrors:
    """Statistics of one axis; NaN entries of ``measured_mm`` are readings that did not measure it.

    Examples
    --------
    >>> r = axis_errors([0.0, np.nan, 2.5, 0.0], 0.5)
    >>> r.n, round(r.ap_mm, 4), round(r.spread_3s_mm, 4), r.max_abs_error_mm, round(r.mean_abs_error_mm, 4)
    (3, 0.3333, 4.3301, 2.0, 1.0)
    >>> axis_errors([np.nan, np.nan], 0.5)
    AxisErrors(n=0, ap_mm=None, spread_3s_mm=None, max_abs_error_mm=None, mean_abs_error_mm=None)
    """
    values = np.asarray(measured_mm, dtype=float).reshape(-1)
    if np.isinf(values).any() or not math.isfinite(commanded_mm):
        raise ConfigError(
            f"axis readings {values.tolist()} against {commanded_mm!r}: expected finite numbers or NaN "
            "(not measured), and a finite command"
        )
    present = values[~np.isnan(values)]
    n = len(present)
    if n == 0:
        return AxisErrors(0, None, None, None, None)
    errors = np.abs(present - commanded_mm)
    spread = pose_repeatability(present[:, None]).spread_3s_axes_mm[0] if n >= 2 else None
    return AxisErrors(
        n,
        pose_accuracy(present[:, None], [commanded_mm]).ap_axes_mm[0],
        spread,
        float(errors.max()),
        float(errors.mean()),
    )


def partial_pose_statistics(measured_mm: ArrayLike, commanded_mm: ArrayLike) -> PartialPoseStatistics:
    """Per-axis statistics (each over its own readings) and spatial AP/RP over the complete readings.

    Parameters
    ----------
    measured_mm : array_like, shape (n, 3)
        One reading per row, mm; NaN where the axis was not measured.
    commanded_mm : array_like, shape (3,)
        The command position, mm.

    Examples
    --------
    >>> s = partial_pose_statistics([[0.0, 0.0, np.nan], [2.5, 0.0, -200.0], [np.nan, np.nan, np.nan]],
    ...                             [0.0, 0.0, -200.0])
    >>> [a.n for a in s.axes], s.n_complete, s.ap_mm, s.rp_mm
    ([2, 2, 1], 1, 2.5, None)
    """
    readings = np.asarray(measured_mm, dtype=float)
    command = np.asarray(commanded_mm, dtype=float)
    if readings.ndim != 2 or readings.shape[1] != 3 or command.shape != (3,):
        raise ConfigError(
            f"measured_mm shape {readings.shape} and commanded_mm shape {command.shape}: expected (n, 3) and (3,)"
        )
    axes = tuple(axis_errors(readings[:, k], float(command[k])) for k in range(3))
    complete = readings[~np.isnan(readings).any(axis=1)]
    ap = pose_accuracy(complete, command).ap_mm if len(complete) >= 1 else None
    rp = pose_repeatability(complete).rp_mm if len(complete) >= 2 else None
    return PartialPoseStatistics(len(readings), axes, len(complete), ap, rp)


def detection_rate(detected: ArrayLike, *, k: float = 2.0) -> DetectionRate:
    """Rate of detections (entries 0/1 or bool) with its Wilson score interval at z = ``k`` (the coverage factor,
    2 throughout bench: about 95 %). Unlike p ± k·√(p(1-p)/n) it stays in [0, 1] and is not empty at 0 or n of n.
    The one Wilson interval of bench: the laser grid's screen detections and hit rates
    (:func:`bench.metrology.hit_rate.grid_hit_rates`) both use it. No readings give rate and interval ``None``.

    Examples
    --------
    >>> r = detection_rate([1, 0, 0, 1, 0, 0])
    >>> r.k, r.n, round(r.rate, 4), round(r.low, 4), round(r.high, 4)
    (2, 6, 0.3333, 0.0945, 0.7055)
    >>> r = detection_rate([1] * 397 + [0] * 3)   # delta thesis Appendix D2, 140 mm: 397 hits in 400 attempts
    >>> r.rate, round(r.low, 4), round(r.high, 4)
    (0.9925, 0.9778, 0.9975)
    >>> detection_rate([])
    DetectionRate(k=0, n=0, rate=None, low=None, high=None)
    """
    if not k > 0:
        raise ConfigError(f"k = {k}, expected a coverage factor > 0")
    flags = np.asarray(detected, dtype=float).reshape(-1)
    if not np.isin(flags, (0.0, 1.0)).all():
        raise ConfigError(f"detections {flags.tolist()}: expected 0 or 1 per reading")
    hits, n = int(flags.sum()), len(flags)
    if n == 0:
        return DetectionRate(0, 0, None, None, None)
    p = hits / n
    centre = (p + k * k / (2 * n)) / (1 + k * k / n)
    half = k * math.sqrt(p * (1 - p) / n + k * k / (4 * n * n)) / (1 + k * k / n)
    return DetectionRate(hits, n, p, max(0.0, centre - half), min(1.0, centre + half))


def rate_text(rate: DetectionRate, *, counts: bool = True) -> str:
    """A rate as bench prints it: ``k / n, rate [low, high]`` in %, the rate to 0.01 % (the thesis's 99.25 %), the
    Wilson bounds to 0.1 %; without ``k / n`` when ``counts`` is False (a table with its own column for them);
    :data:`NO_READING` for n = 0. The one formatter of ``bench analyze grid-positioning`` and the laser-grid reports.

    Examples
    --------
    >>> rate_text(detection_rate([1, 1, 1, 0]))
    '3 / 4, 75.00 % [29.4, 95.6]'
    >>> rate_text(detection_rate([1] * 397 + [0] * 3), counts=False), rate_text(detection_rate([]))
    ('99.25 % [97.8, 99.7]', 'no reading')
    """
    if rate.n == 0 or rate.rate is None or rate.low is None or rate.high is None:
        return NO_READING
    text = f"{100 * rate.rate:.2f} % [{100 * rate.low:.1f}, {100 * rate.high:.1f}]"
    return f"{rate.k} / {rate.n}, {text}" if counts else text


# -- tidy-table interface of the laser-grid positioning test ---------------------------------------------------------

#: Columns of a grid positioning table (``bench export RUN --kind pose`` of ``delta_positioning``); ``x_mm``,
#: ``y_mm``, ``z_mm`` may be missing or have empty cells (not measured).
GRID_COLUMNS = (
    "pose",
    "cycle",
    "cmd_x_mm",
    "cmd_y_mm",
    "cmd_z_mm",
    "horizontal_valid",
    "vertical_valid",
    "horizontal_hits",
    "vertical_hits",
)
#: Which screens can measure each axis (delta4-lasergrid.md §4.6 step 7).
_AXIS_SCREENS = {"x_mm": ("horizontal",), "y_mm": ("horizontal", "vertical"), "z_mm": ("vertical",)}
_SCREEN_AXES = {"horizontal": ("x_mm", "y_mm"), "vertical": ("y_mm", "z_mm")}


@dataclass(frozen=True)
class GridPoseResult:
    """One pose of a laser-grid positioning run: statistics over measured axes and each screen's detection."""

    pose: str
    commanded_mm: tuple[float, float, float]
    statistics: PartialPoseStatistics
    valid: dict[str, DetectionRate]  #: per screen: readings whose axes were stored
    lit: dict[str, DetectionRate]  #: per screen: readings with at least one sensor lit


def grid_positioning_table(frame: pd.DataFrame) -> pd.DataFrame:
    """Check a grid positioning table, strings (:func:`bench.metrology.tables.read_table_csv`) or numbers (the
    store's tidy table), and return it with numbers as float; an empty axis cell (or NaN) is NaN, "not measured".
    Every stored axis must come from a screen marked valid, and a valid screen must have stored both its axes."""
    from bench.metrology.tables import numeric_columns

    source = frame.attrs.get("source", "table")
    table = numeric_columns(frame, GRID_COLUMNS[1:])
    for column in _AXIS_SCREENS:
        text = frame[column].astype(str).str.strip() if column in frame.columns else None
        if text is None:
            table[column] = np.nan
            continue
        missing = frame[column].isna() | text.str.lower().isin(["", "nan", "none"])  # pandas 3 keeps NaN
        table[column] = np.nan
        table.loc[~missing, column] = numeric_columns(frame[~missing], [column])[column]
    for column, screens in _AXIS_SCREENS.items():
        stored = table[column].notna()
        from_valid = np.logical_or.reduce([table[f"{s}_valid"] == 1 for s in screens])
        _refuse_first(
            source,
            stored & ~from_valid,
            column,
            frame,
            f"expected it only with {' or '.join(f'{s}_valid = 1' for s in screens)}",
        )
    for screen, axes in _SCREEN_AXES.items():
        flags = table[f"{screen}_valid"]
        _refuse_first(source, ~flags.isin([0.0, 1.0]), f"{screen}_valid", frame, "expected 0 or 1")
        for column in axes:
            _refuse_first(
                source,
                (flags == 1) & table[column].isna(),
                column,
                frame,
                f"empty while {screen}_valid = 1, expected the value that screen measured",
            )
    table["pose"] = frame["pose"].astype(str).str.strip()
    table.attrs["source"] = source
    return table


def _refuse_first(source: str, bad: pd.Series, column: str, frame: pd.DataFrame, expected: str) -> None:
    """ConfigError naming the first bad row (1-based), the column and the cell as written."""
    if bad.any():
        index = bad.idxmax()
        cell = frame.at[index, column] if column in frame.columns else ""
        raise ConfigError(f"{source}: row {int(index) + 1}, column {column}: {str(cell).strip()!r}, {expected}")


def analyze_grid_positioning(table: pd.DataFrame, *, k: float = 2.0) -> list[GridPoseResult]:
    """Per pose (in order of appearance): detection per screen, with its Wilson interval at z = ``k``
    (:func:`detection_rate`), and per-axis statistics of the stored readings."""
    results = []
    for pose, rows in table.groupby("pose", sort=False):
        commands = rows[["cmd_x_mm", "cmd_y_mm", "cmd_z_mm"]].drop_duplicates()
        if len(commands) != 1:
            raise ConfigError(
                f"{table.attrs.get('source', 'table')}: pose {pose!r} has {len(commands)} commanded "
                "positions, expected one"
            )
        cx, cy, cz = (float(v) for v in commands.iloc[0])
        command = (cx, cy, cz)
        statistics = partial_pose_statistics(rows[["x_mm", "y_mm", "z_mm"]].to_numpy(float), command)
        screens = ("horizontal", "vertical")
        results.append(
            GridPoseResult(
                str(pose),
                command,
                statistics,
                valid={s: detection_rate(rows[f"{s}_valid"], k=k) for s in screens},
                lit={s: detection_rate(rows[f"{s}_hits"] > 0, k=k) for s in screens},
            )
        )
    return results


def pooled_axis_errors(table: pd.DataFrame) -> tuple[AxisErrors, ...]:
    """The thesis's summary over every pose (§8.4.2): per axis, the errors x_j - x_c of all stored readings."""
    commanded = table[["cmd_x_mm", "cmd_y_mm", "cmd_z_mm"]].to_numpy(float)
    errors = table[["x_mm", "y_mm", "z_mm"]].to_numpy(float) - commanded
    return tuple(axis_errors(errors[:, k], 0.0) for k in range(3))


def _rate_json(rate: DetectionRate) -> dict[str, object]:
    return {"k": rate.k, "n": rate.n, "rate": rate.rate, "wilson": [rate.low, rate.high]}


def axis_json(axis: AxisErrors) -> dict[str, object]:
    """One axis as JSON (``null`` where there are too few readings)."""
    return {
        "n": axis.n,
        "AP_mm": axis.ap_mm,
        "spread_3s_mm": axis.spread_3s_mm,
        "max_abs_error_mm": axis.max_abs_error_mm,
        "mean_abs_error_mm": axis.mean_abs_error_mm,
    }


def grid_pose_json(result: GridPoseResult) -> dict[str, object]:
    """One pose as JSON: screens (valid and lit rates: k of n, rate, Wilson interval at the analysis's z), axes,
    complete readings, spatial AP and RP."""
    s = result.statistics
    return {
        "commanded_mm": list(result.commanded_mm),
        "n": s.n_readings,
        "screens": {
            name: {"valid": _rate_json(result.valid[name]), "lit": _rate_json(result.lit[name])}
            for name in result.valid
        },
        "axes": {name: axis_json(axis) for name, axis in zip(AXIS_NAMES, s.axes)},
        "n_complete": s.n_complete,
        "AP_mm": s.ap_mm,
        "RP_mm": s.rp_mm,
    }
