"""Tidy-table interface for multi-directional poses, sampled paths and positioning-time steps.

Row order carries no meaning in any of these tables: samples are ordered by ``t_s`` within a cycle, stations by
their ``station`` number, approach directions by name. Tables:

- multi-directional pose table (ISO 9283 7.2.3): a pose table (`bench.metrology.tables`) whose pose labels name
  the approach direction after a slash, ``P1/+x``, ``P1/-y``, ``P1/+z``;
- path table (8.2-8.6): ``cycle, t_s, x_mm, y_mm[, z_mm]``, optionally ``a_deg, b_deg, c_deg``;
- station table (the commanded path): ``station, x_mm, y_mm[, z_mm]``, optionally the commanded angles;
- positioning table (clause 9): ``step, cycle, t_s, x_mm, y_mm[, z_mm]``.

Bad cells raise ``ConfigError`` naming the source, row, column and value.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from bench.errors import ConfigError
from bench.metrology.iso9283 import (
    MultidirectionalVariation,
    OrientationVariation,
    multidirectional_variation,
    orientation_multidirectional_variation,
)
from bench.metrology.tables import ANGLE_PAIRS, condition_groups, numeric_columns

__all__ = [
    "MultidirectionalResult",
    "PathCycle",
    "analyze_multidirectional",
    "path_cycles",
    "path_table",
    "positioning_steps",
    "station_table",
]

_ANGLES = tuple(attained for _, attained in ANGLE_PAIRS)


@dataclass(frozen=True)
class MultidirectionalResult:
    """vAP of one base pose (and set of conditions) from its approach directions."""

    label: str  #: the base pose, with the conditions when they vary (``P1 (velocity_pct=50)``)
    pose: str  #: the base pose, ``P1``
    conditions: tuple[tuple[str, float], ...]
    directions: tuple[str, ...]  #: the direction labels, sorted (``P1/+x``, ``P1/+z``, ``P1/-y``)
    n_per_direction: tuple[int, ...]
    position: MultidirectionalVariation
    orientation: OrientationVariation | None  #: when the table has attained angles
    angle_names: tuple[str, ...]  #: ``("a", "b")`` for the angles present


@dataclass(frozen=True, eq=False)
class PathCycle:
    """One cycle of a path table, samples in time order."""

    cycle: int
    t_s: np.ndarray  #: (k,)
    position_mm: np.ndarray  #: (k, d)
    angles_deg: np.ndarray | None  #: (k, q) when the table has angle columns


def _positions(frame: pd.DataFrame) -> list[str]:
    return ["x_mm", "y_mm", *(["z_mm"] if "z_mm" in frame.columns else [])]


def _angles(frame: pd.DataFrame) -> list[str]:
    return [c for c in _ANGLES if c in frame.columns]


def analyze_multidirectional(table: pd.DataFrame) -> list[MultidirectionalResult]:
    """vAP_p (and vAP_a/b/c when angles were measured) per base pose of a checked pose table (ISO 9283 7.2.3).

    The pose label ``P1/+x`` is pose P1 approached from +x; every direction of a pose is one cloud for
    :func:`~bench.metrology.iso9283.multidirectional_variation`. Groups by the conditions where they vary.
    """
    source = table.attrs.get("source", "table")
    base = table["pose"].str.split("/", n=1).str[0]
    grouped = table.assign(pose=base, direction=table["pose"])
    positions, angles = ["x_mm", "y_mm", "z_mm"], _angles(table)
    results = []
    for label, pose, conditions, rows in condition_groups(grouped):
        directions = tuple(sorted(rows["direction"].unique()))
        if len(directions) < 2:
            raise ConfigError(
                f"{source}: pose {pose!r} has {len(directions)} approach direction(s) "
                f"({', '.join(directions)}), expected labels like {pose}/+x, {pose}/-y, {pose}/+z"
            )
        clouds = [rows[rows["direction"] == d] for d in directions]
        orientation = orientation_multidirectional_variation([c[angles].to_numpy() for c in clouds]) if angles else None
        results.append(
            MultidirectionalResult(
                label=label,
                pose=pose,
                conditions=conditions,
                directions=directions,
                n_per_direction=tuple(len(c) for c in clouds),
                position=multidirectional_variation([c[positions].to_numpy() for c in clouds]),
                orientation=orientation,
                angle_names=tuple(a[0] for a in angles),
            )
        )
    return results


def _ordered(frame: pd.DataFrame, keys: list[str], what: str) -> pd.DataFrame:
    source = frame.attrs.get("source", "table")
    duplicated = frame.duplicated(keys)
    if duplicated.any():
        index = duplicated.idxmax()
        values = ", ".join(f"{k} {frame.at[index, k]:g}" for k in keys)
        raise ConfigError(f"{source}: row {int(index) + 1}: {values} repeated, expected one row per {what}")
    return frame.sort_values(keys, kind="stable")


def path_table(frame: pd.DataFrame) -> pd.DataFrame:
    """Check a path table (``cycle, t_s, x_mm, y_mm[, z_mm][, a_deg..]``); numbers as float, sorted by cycle, t_s."""
    table = numeric_columns(frame, ["cycle", "t_s", *_positions(frame)])
    table = numeric_columns(table, _angles(frame), required=False)
    table.attrs["source"] = frame.attrs.get("source", "table")
    if table.empty:
        raise ConfigError(f"{table.attrs['source']}: no rows, expected sampled paths")
    return _ordered(table, ["cycle", "t_s"], "cycle and time")


def path_cycles(table: pd.DataFrame) -> list[PathCycle]:
    """The cycles of a checked path table, in cycle order, each in time order."""
    positions, angles = _positions(table), _angles(table)
    return [
        PathCycle(
            int(cycle),
            rows["t_s"].to_numpy(float),
            rows[positions].to_numpy(float),
            rows[angles].to_numpy(float) if angles else None,
        )
        for cycle, rows in table.groupby("cycle", sort=True)
    ]


def station_table(frame: pd.DataFrame) -> tuple[np.ndarray, np.ndarray | None, tuple[str, ...]]:
    """Commanded stations in order of travel: positions (m, d), angles (m, q) or None, and the angle columns."""
    positions, angles = _positions(frame), _angles(frame)
    table = numeric_columns(frame, ["station", *positions])
    table = numeric_columns(table, angles, required=False)
    table.attrs["source"] = frame.attrs.get("source", "table")
    table = _ordered(table, ["station"], "station")
    return (table[positions].to_numpy(float), table[angles].to_numpy(float) if angles else None, tuple(angles))


def positioning_steps(frame: pd.DataFrame) -> tuple[tuple[int, ...], list[list[tuple[np.ndarray, np.ndarray]]]]:
    """Step numbers and, per step and cycle (both in order), the (t_s, position_mm) of a positioning table."""
    positions = _positions(frame)
    table = numeric_columns(frame, ["step", "cycle", "t_s", *positions])
    table.attrs["source"] = frame.attrs.get("source", "table")
    if table.empty:
        raise ConfigError(f"{table.attrs['source']}: no rows, expected the samples of positioning steps")
    table = _ordered(table, ["step", "cycle", "t_s"], "step, cycle and time")
    numbers, steps = [], []
    for step, rows in table.groupby("step", sort=True):
        numbers.append(int(step))
        steps.append(
            [(r["t_s"].to_numpy(float), r[positions].to_numpy(float)) for _, r in rows.groupby("cycle", sort=True)]
        )
    return tuple(numbers), steps
