"""Hit rates of a sensor-hit test (the delta thesis's laser-grid hit repeatability, delta4-lasergrid.md §7.3).

Each attempt commands the end effector onto one sensor and records whether that sensor was reported
(``hit_expected``) and whether any sensor was (``hit_any``). The thesis's "repeatability" is the fraction of
attempts that hit, per sensor and over the group of sensors at one height (Appendix D2: 397/400 = 0.9925 at
140 mm). A fraction of n Bernoulli trials is given with its Wilson score interval at z = k (k = 2: about 95 %),
which, unlike p ± k·√(p(1-p)/n), stays inside [0, 1] and is not empty at 25 of 25.

A tidy table (``bench export RUN --kind grid_hit``) has one row per attempt: ``cmd_x_mm, cmd_y_mm, cmd_z_mm``,
``expected_i, expected_j, expected_index``, ``hit_expected``, ``hit_any`` (0 or 1).
"""

from __future__ import annotations

from dataclasses import dataclass

import pandas as pd

from bench.errors import ConfigError, InsufficientData
from bench.metrology.partial_pose import DetectionRate as HitRate
from bench.metrology.partial_pose import detection_rate
from bench.metrology.tables import numeric_columns

__all__ = ["GRID_HIT_COLUMNS", "GridHits", "HeightHits", "HitRate", "SensorHits", "grid_hit_rates", "hit_rate"]

#: Columns a grid-hit table needs.
GRID_HIT_COLUMNS = ("cmd_x_mm", "cmd_y_mm", "cmd_z_mm", "expected_i", "expected_j", "expected_index", "hit_expected",
                    "hit_any")


@dataclass(frozen=True)
class SensorHits:
    """One sensor at one height."""

    height_mm: float  #: below the base (positive), -cmd_z_mm
    i: int
    j: int
    index: int  #: the sensor index the grid reports
    x_mm: float
    y_mm: float
    expected: HitRate  #: the commanded sensor was reported
    any: HitRate  #: some sensor was reported


@dataclass(frozen=True)
class HeightHits:
    """Every sensor at one height together (the thesis's group figure)."""

    height_mm: float
    sensors: int
    expected: HitRate
    any: HitRate


@dataclass(frozen=True)
class GridHits:
    sensors: tuple[SensorHits, ...]  #: in order of appearance
    heights: tuple[HeightHits, ...]


def hit_rate(outcomes, *, k: float = 2.0) -> HitRate:
    """Fraction of successful attempts (0/1 each) with its Wilson score interval at z = ``k``
    (:func:`bench.metrology.partial_pose.detection_rate`).

    Examples
    --------
    >>> r = hit_rate([1] * 397 + [0] * 3)
    >>> r.k, r.n, r.rate, round(r.low, 4), round(r.high, 4)
    (397, 400, 0.9925, 0.9778, 0.9975)

    Appendix D2 at 140 mm: 397 hits in 400 attempts.
    """
    if not k > 0:
        raise ConfigError(f"k = {k}, expected > 0")
    rate = detection_rate(outcomes, z=k)
    if rate.n == 0:
        raise InsufficientData("hit rate: 0 attempts, at least 1 required")
    return rate


def grid_hit_rates(frame: pd.DataFrame, *, k: float = 2.0) -> GridHits:
    """Hit rates per sensor and height, and per height over every sensor, of a grid-hit table.

    ``frame`` may hold strings (:func:`bench.metrology.tables.read_table_csv`) or numbers (the store's tidy
    table); bad cells raise ``ConfigError`` naming the row and column.
    """
    table = numeric_columns(frame, GRID_HIT_COLUMNS)
    if table.empty:
        raise InsufficientData(f"{frame.attrs.get('source', 'table')}: no grid-hit attempts")
    keys = ["cmd_z_mm", "expected_i", "expected_j"]
    sensors = []
    for (z, i, j), rows in table.groupby(keys, sort=False):
        sensors.append(SensorHits(-float(z), int(i), int(j), int(rows["expected_index"].iloc[0]),
                                  float(rows["cmd_x_mm"].iloc[0]), float(rows["cmd_y_mm"].iloc[0]),
                                  hit_rate(rows["hit_expected"], k=k), hit_rate(rows["hit_any"], k=k)))
    heights = []
    for z, rows in table.groupby("cmd_z_mm", sort=False):
        count = len(rows.groupby(keys[1:]))
        heights.append(HeightHits(-float(z), count, hit_rate(rows["hit_expected"], k=k),
                                  hit_rate(rows["hit_any"], k=k)))
    return GridHits(tuple(sensors), tuple(heights))
