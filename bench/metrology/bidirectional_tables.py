"""Bidirectional positioning tables (one row per reading) to ISO 230-2 figures per axis.

A table has ``target_mm``, ``reading_mm`` and ``direction`` (``up``/``down``, also ``+``/``-`` or
``forward``/``backward``: the direction of the approach to the target), optionally ``axis`` (one result per axis).
Row order carries no meaning: readings are grouped by target, and every figure of
:func:`~bench.metrology.actuator.positioning_iso230_2` is a per-target statistic, so no pairing across targets is
needed. Every target needs the same number of approaches per direction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from bench.errors import ConfigError
from bench.metrology.actuator import PositioningIso2302, positioning_iso230_2
from bench.metrology.tables import numeric_columns

__all__ = ["BidirectionalResult", "analyze_bidirectional"]

_DIRECTIONS = {"up": "up", "+": "up", "forward": "up", "down": "down", "-": "down", "backward": "down"}


@dataclass(frozen=True, eq=False)
class BidirectionalResult:
    """ISO 230-2 figures of one axis with the readings they come from."""

    axis: str
    targets_mm: np.ndarray  #: (m,) ascending
    forward_mm: np.ndarray  #: (n, m) readings approached from below (↑)
    backward_mm: np.ndarray  #: (n', m) readings approached from above (↓)
    result: PositioningIso2302


def _readings(rows: pd.DataFrame, targets: np.ndarray, direction: str, where: str) -> np.ndarray:
    columns = []
    for target in targets:
        values = rows.loc[rows["target_mm"] == target, "reading_mm"].to_numpy(float)
        if len(values) == 0:
            raise ConfigError(f"{where}: target {target:g} mm has no {direction} approach, expected both directions")
        columns.append(values)
    counts = {len(c) for c in columns}
    if len(counts) != 1:
        per = ", ".join(f"{t:g}: {len(c)}" for t, c in zip(targets, columns))
        raise ConfigError(f"{where}: {direction} approaches per target differ ({per}), expected the same number")
    return np.column_stack(columns)


def analyze_bidirectional(frame: pd.DataFrame) -> list[BidirectionalResult]:
    """ISO 230-2 unidirectional and bidirectional figures (reversal B, R, E, M, A) per axis of a table."""
    source = frame.attrs.get("source", "table")
    if "direction" not in frame.columns:
        raise ConfigError(f"{source}: missing column direction (up/down), expected bidirectional approaches")
    table = numeric_columns(frame, ["target_mm", "reading_mm"])
    if table.empty:
        raise ConfigError(f"{source}: no rows, expected readings of bidirectional approaches")
    direction = frame["direction"].astype(str).str.strip().str.lower()
    unknown = ~direction.isin(list(_DIRECTIONS))
    if unknown.any():
        index = unknown.idxmax()
        raise ConfigError(f"{source}: row {int(index) + 1}, column direction: {frame.at[index, 'direction']!r}, "
                          "expected up or down (+/-, forward/backward)")
    table["direction"] = direction.map(_DIRECTIONS)
    table["axis"] = frame["axis"].astype(str).str.strip() if "axis" in frame.columns else "1"
    results = []
    for axis, rows in table.groupby("axis", sort=True):
        where = f"{source}, axis {axis}"
        targets = np.sort(rows["target_mm"].unique())
        forward = _readings(rows[rows["direction"] == "up"], targets, "up", where)
        backward = _readings(rows[rows["direction"] == "down"], targets, "down", where)
        results.append(BidirectionalResult(str(axis), targets, forward, backward,
                                           positioning_iso230_2(targets, forward, backward)))
    return results
