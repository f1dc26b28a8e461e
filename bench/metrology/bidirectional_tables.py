"""Bidirectional positioning tables (one row per reading) to ISO 230-2 figures per axis.

A table has ``target_mm``, ``reading_mm`` and ``direction`` (``up``/``down``, also ``+``/``-``, ``forward``/``backward``
or a signed number, +1 / -1: the direction of the approach to the target), optionally ``axis`` (one result per
axis). The export of a bidirectional ``actuator_accuracy`` run (``bench export RUN --kind actuator_travel``) is read
as such a table: ``cmd_travel_mm`` (or ``cmd_mm``) is the target, ``travel_mm`` the reading, ``actuator`` the axis
and ``direction`` +1 (↑) or -1 (↓).
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

__all__ = ["BidirectionalResult", "analyze_bidirectional", "approach_directions"]

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


#: Columns of an actuator travel table (an exported ``actuator_accuracy`` run) and the names they stand for here.
_ACTUATOR_ALIASES = (
    ("cmd_travel_mm", "target_mm"),
    ("cmd_mm", "target_mm"),
    ("travel_mm", "reading_mm"),
    ("actuator", "axis"),
)


def _aliased(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` with the actuator travel columns renamed to target_mm, reading_mm and axis where those are absent."""
    renames: dict[str, str] = {}
    for column, name in _ACTUATOR_ALIASES:
        if column in frame.columns and name not in frame.columns and name not in renames.values():
            renames[column] = name
    if not renames:
        return frame
    renamed = frame.rename(columns=renames)
    renamed.attrs = dict(frame.attrs)
    return renamed


def approach_directions(column: pd.Series) -> pd.Series:
    """``up`` or ``down`` per cell of a direction column (NaN where it is neither): up/down, +/-,
    forward/backward, or a signed number read by its sign (+1 up, -1 down)."""
    numbers = pd.to_numeric(column, errors="coerce")
    text = column.astype(str).str.strip().str.lower()
    signed = numbers.notna() & (numbers != 0) & ~text.isin(["+", "-"])
    return text.where(~signed, np.where(numbers > 0, "up", "down")).map(_DIRECTIONS)


def analyze_bidirectional(frame: pd.DataFrame) -> list[BidirectionalResult]:
    """ISO 230-2 unidirectional and bidirectional figures (reversal B, R, E, M, A) per axis of a table.

    The figures are those of :func:`bench.metrology.actuator.positioning_iso230_2` (iso9283.md §7.1 [U]): with
    x_ij the deviation reading - target of approach j to target i, B_i = x̄_i↑ - x̄_i↓ and B = max |B_i|;
    R_i = max(2 s_i↑ + 2 s_i↓ + |B_i|, R_i↑, R_i↓), R_i↑ = 4 s_i↑, R = max R_i; A = max_i(x̄_i↑ + 2 s_i↑,
    x̄_i↓ + 2 s_i↓) - min_i(x̄_i↑ - 2 s_i↑, x̄_i↓ - 2 s_i↓).
    """
    frame = _aliased(frame)
    source = frame.attrs.get("source", "table")
    if "direction" not in frame.columns:
        raise ConfigError(f"{source}: missing column direction (up/down), expected bidirectional approaches")
    table = numeric_columns(frame, ["target_mm", "reading_mm"])
    if table.empty:
        raise ConfigError(f"{source}: no rows, expected readings of bidirectional approaches")
    direction = approach_directions(frame["direction"])
    unknown = direction.isna()
    if unknown.any():
        index = unknown.idxmax()
        raise ConfigError(
            f"{source}: row {int(index) + 1}, column direction: {frame.at[index, 'direction']!r}, "
            "expected up or down (+/-, forward/backward, +1/-1)"
        )
    table["direction"] = direction
    axis = frame["axis"] if "axis" in frame.columns else pd.Series("1", index=frame.index)
    numbers = pd.to_numeric(axis, errors="coerce")  # an exported actuator number (2.0) reads as "2"
    whole = numbers.notna() & (numbers == numbers.round())
    table["axis"] = axis.astype(str).str.strip().where(~whole, numbers.round().astype("Int64").astype(str))
    results = []
    for axis, rows in table.groupby("axis", sort=True):
        where = f"{source}, axis {axis}"
        targets = np.sort(rows["target_mm"].unique())
        forward = _readings(rows[rows["direction"] == "up"], targets, "up", where)
        backward = _readings(rows[rows["direction"] == "down"], targets, "down", where)
        results.append(
            BidirectionalResult(str(axis), targets, forward, backward, positioning_iso230_2(targets, forward, backward))
        )
    return results
