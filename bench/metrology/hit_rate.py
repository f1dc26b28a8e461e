"""Hit rates of a sensor-hit test (the delta thesis's laser-grid hit repeatability, delta4-lasergrid.md §7.3).

Each attempt commands the end effector onto one sensor and records whether that sensor was reported
(``hit_expected``) and whether any sensor was (``hit_any``). The thesis's "repeatability" is the fraction of
attempts that hit, per sensor and over the group of sensors at one height (Appendix D2: 397/400 = 0.9925 at
140 mm). A fraction of n Bernoulli trials is given with its Wilson score interval at z = k (k = 2: about 95 %),
which, unlike p ± k·√(p(1-p)/n), stays inside [0, 1] and is not empty at 25 of 25: the one Wilson interval of
bench, :func:`bench.metrology.partial_pose.detection_rate` (``HitRate`` is its result type).

A tidy table (``bench export RUN --kind grid_hit``) has one row per attempt: ``cmd_x_mm, cmd_y_mm, cmd_z_mm``,
``expected_i, expected_j, expected_index``, ``hit_expected``, ``hit_any`` (0 or 1).
"""

from __future__ import annotations

from dataclasses import dataclass

import pandas as pd

from bench.errors import InsufficientData
from bench.metrology.partial_pose import DetectionRate as HitRate
from bench.metrology.partial_pose import detection_rate
from bench.metrology.tables import numeric_columns

__all__ = ["GRID_HIT_COLUMNS", "GridHits", "HeightHits", "HitRate", "SensorHits", "grid_hit_rates"]

#: Columns a grid-hit table needs.
GRID_HIT_COLUMNS = (
    "cmd_x_mm",
    "cmd_y_mm",
    "cmd_z_mm",
    "expected_i",
    "expected_j",
    "expected_index",
    "hit_expected",
    "hit_any",
)


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


def grid_hit_rates(frame: pd.DataFrame, *, k: float = 2.0) -> GridHits:
    """Hit rates per sensor and height, and per height over every sensor, of a grid-hit table.

    ``frame`` may hold strings (:func:`bench.metrology.tables.read_table_csv`) or numbers (the store's tidy
    table); bad cells raise ``ConfigError`` naming the row and column. Rates and Wilson intervals (z = ``k``) are
    :func:`bench.metrology.partial_pose.detection_rate`'s.

    Examples
    --------
    >>> frame = pd.DataFrame({"cmd_x_mm": [-65.0] * 4, "cmd_y_mm": [-65.0] * 4, "cmd_z_mm": [-140.0] * 4,
    ...                       "expected_i": [1] * 4, "expected_j": [1] * 4, "expected_index": [17] * 4,
    ...                       "hit_expected": [1, 1, 0, 1], "hit_any": [1, 1, 1, 1]})
    >>> hits = grid_hit_rates(frame)
    >>> s = hits.sensors[0]
    >>> s.height_mm, (s.i, s.j, s.index), (s.expected.k, s.expected.n), round(s.expected.low, 4), s.any.rate
    (140.0, (1, 1, 17), (3, 4), 0.2943, 1.0)
    """
    table = numeric_columns(frame, GRID_HIT_COLUMNS)
    if table.empty:
        raise InsufficientData(f"{frame.attrs.get('source', 'table')}: no grid-hit attempts")
    keys = ["cmd_z_mm", "expected_i", "expected_j"]
    sensors = []
    for (z, i, j), rows in table.groupby(keys, sort=False):
        sensors.append(
            SensorHits(
                -float(z),
                int(i),
                int(j),
                int(rows["expected_index"].iloc[0]),
                float(rows["cmd_x_mm"].iloc[0]),
                float(rows["cmd_y_mm"].iloc[0]),
                detection_rate(rows["hit_expected"], k=k),
                detection_rate(rows["hit_any"], k=k),
            )
        )
    heights = []
    for z, rows in table.groupby("cmd_z_mm", sort=False):
        count = len(rows.groupby(keys[1:]))
        heights.append(
            HeightHits(
                -float(z), count, detection_rate(rows["hit_expected"], k=k), detection_rate(rows["hit_any"], k=k)
            )
        )
    return GridHits(tuple(sensors), tuple(heights))
