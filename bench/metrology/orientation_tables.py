"""Tidy tables of tilt readings -> orientation AP/RP per pose (ISO 9283 7.2.1, 7.2.2) with the calliper budget.

The table is what ``bench export RUN --kind tilt`` writes for a ``dissertation_pose`` alpha/beta run: ``pose``,
``cycle``, ``cmd_a_deg``/``a_deg`` (alpha) or ``cmd_b_deg``/``b_deg`` (beta), and the condition columns. A pose
table that also has positions (``x_mm`` ...) is read the same way; its positions are ignored here. A run that stored
the two calliper depths instead (``tilt_entry = "depths"``, ``bench export RUN --kind tilt_depth``: ``depth1_mm``,
``depth2_mm``, ``hole_spacing_mm``) is turned into tilts first (:func:`tilts_from_depths`). Row order carries no
meaning: each pose's readings are taken in cycle order.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import pandas as pd

from bench.errors import ConfigError, InsufficientData
from bench.metrology.formatting import natural_key
from bench.metrology.orientation import OrientationFigures, TiltGauge, orientation_figures
from bench.metrology.tables import (
    ANGLE_PAIRS,
    CONDITION_COLUMNS,
    _check_constant_command,
    _check_unique_cycles,
    condition_groups,
    numeric_columns,
    with_pose_labels,
)

__all__ = [
    "DEPTH_COLUMNS",
    "TILT_NUMERIC_COLUMNS",
    "TiltPoseResult",
    "analyze_tilts",
    "orientation_summary",
    "table_spacing_mm",
    "tilt_result_json",
    "tilt_table",
    "tilts_from_depths",
]

#: Columns a tilt table's reader turns into numbers.
TILT_NUMERIC_COLUMNS = ("cycle", *(c for pair in ANGLE_PAIRS for c in pair), *CONDITION_COLUMNS)


@dataclass(frozen=True)
class TiltPoseResult:
    """Orientation figures of one pose under one set of conditions, one entry per measured angle."""

    label: str
    pose: str
    conditions: tuple[tuple[str, float], ...]
    figures: tuple[OrientationFigures, ...]


DEPTH_COLUMNS = ("depth1_mm", "depth2_mm")


def table_spacing_mm(frame: pd.DataFrame) -> float | None:
    """The hole spacing the readings were taken with (column ``hole_spacing_mm``, one value), or None."""
    if "hole_spacing_mm" not in frame.columns:
        return None
    source = frame.attrs.get("source", "table")
    text = frame["hole_spacing_mm"].astype(str).str.strip()
    given = frame["hole_spacing_mm"].notna() & text.notna() & text.ne("") & text.str.lower().ne("nan")
    values = numeric_columns(frame[["hole_spacing_mm"]][given], ["hole_spacing_mm"])
    spacings = sorted(set(values["hole_spacing_mm"]))
    if len(spacings) != 1:
        raise ConfigError(
            f"{source}: column hole_spacing_mm holds {', '.join(f'{v:g}' for v in spacings) or 'nothing'}"
            f", expected the one spacing of the bracket"
        )
    return float(spacings[0])


def tilts_from_depths(frame: pd.DataFrame, spacing_mm: float) -> pd.DataFrame:
    """The tilt of every visit from its two depth readings (000 §8.2.2, §8.6.3; ``sensors.md`` §6.3):

    .. math:: \\theta = \\operatorname{atan2}(h_2 - h_1, s)

    ``frame`` holds one row per reading (``bench export RUN --kind tilt_depth``: ``depth1_mm`` or ``depth2_mm`` set,
    the other empty) or one row per visit with both; rows are joined on pose, cycle and the conditions. Returns one
    row per visit with the commanded angle, the derived angle (``a_deg`` for ``cmd_a_deg`` ...) and both depths.
    A visit without exactly one reading of each depth is a ``ConfigError`` naming it.
    """
    source = frame.attrs.get("source", "table")
    commands = [c for c, _ in ANGLE_PAIRS if c in frame.columns]
    if len(commands) != 1:
        raise ConfigError(
            f"{source}: depth readings with {len(commands)} commanded angle column(s), expected one of "
            f"cmd_a_deg, cmd_b_deg, cmd_c_deg naming the angle the depths measure"
        )
    keys = ["pose", "cycle", *(c for c in CONDITION_COLUMNS if c in frame.columns)]
    table = frame[[*keys, *commands, *DEPTH_COLUMNS]].copy()
    for column in DEPTH_COLUMNS:
        text = table[column].astype(str).str.strip()
        empty = table[column].isna() | text.isna() | text.eq("") | text.str.lower().eq("nan")  # pandas 3 keeps NaN
        table[column] = float("nan")
        if (~empty).any():
            table.loc[~empty, column] = numeric_columns(frame[~empty], [column])[column]
    table = numeric_columns(table, [k for k in keys if k != "pose"] + commands)
    table["pose"] = frame["pose"].astype(str).str.strip()
    rows = []
    for key, visit in table.groupby(keys, sort=True):
        counts = [int(visit[c].notna().sum()) for c in DEPTH_COLUMNS]
        if counts != [1, 1]:
            raise ConfigError(
                f"{source}: pose {key[0]!r}, cycle {key[1]:g}: {counts[0]} depth1_mm and {counts[1]} "
                f"depth2_mm readings, expected one of each"
            )
        h1, h2 = (float(visit[c].dropna().iloc[0]) for c in DEPTH_COLUMNS)
        row = dict(zip(keys, key))
        row.update(
            {
                commands[0]: float(visit[commands[0]].iloc[0]),
                "depth1_mm": h1,
                "depth2_mm": h2,
                commands[0][4:]: math.degrees(math.atan2(h2 - h1, spacing_mm)),
            }
        )
        rows.append(row)
    out = pd.DataFrame(rows)
    out.attrs["source"] = source
    return out


def tilt_table(frame: pd.DataFrame, spacing_mm: float | None = None) -> pd.DataFrame:
    """Check a table of tilt readings; return it with numbers as float and ``pose`` as a stripped string.

    A table of depth readings (``depth1_mm``, ``depth2_mm``, no angle column) is first turned into tilts by
    :func:`tilts_from_depths` with ``spacing_mm`` (the bracket's hole spacing).

    Needs ``pose``, ``cycle`` and at least one measured angle with its command (``a_deg`` with ``cmd_a_deg`` ...);
    a measured angle without its command, or a table without any angle, is a one-line ``ConfigError``.
    """
    source = frame.attrs.get("source", "table")
    missing = [c for c in ("pose", "cycle") if c not in frame.columns]
    if missing:
        raise ConfigError(f"{source}: missing column(s) {', '.join(missing)}; found {', '.join(frame.columns)}")
    if set(DEPTH_COLUMNS) <= set(frame.columns) and not any(a in frame.columns for _, a in ANGLE_PAIRS):
        if spacing_mm is None:
            raise ConfigError(
                f"{source}: depth readings without a hole spacing, expected a hole_spacing_mm column or --spacing-mm"
            )
        frame = tilts_from_depths(frame, spacing_mm).astype({"pose": str})
    for command, attained in ANGLE_PAIRS:
        if attained in frame.columns and command not in frame.columns:
            raise ConfigError(f"{source}: column {attained} given without {command}")
    pairs = [pair for pair in ANGLE_PAIRS if pair[1] in frame.columns]
    if not pairs:
        raise ConfigError(
            f"{source}: no measured angle (a_deg, b_deg or c_deg with cmd_a_deg ...), expected the "
            f"tilt readings of an alpha or beta run (bench export RUN --kind tilt)"
        )
    columns = [
        "pose",
        "cycle",
        *(c for pair in pairs for c in pair),
        *(c for c in CONDITION_COLUMNS if c in frame.columns),
    ]
    return with_pose_labels(numeric_columns(frame[columns], columns[1:]), frame, source)


def analyze_tilts(table: pd.DataFrame, gauge: TiltGauge | None = None, *, k: float = 2.0) -> list[TiltPoseResult]:
    """AP/RP of every measured angle per pose and set of conditions of a checked tilt table (:func:`tilt_table`),
    through :func:`bench.metrology.orientation.orientation_figures` with the calliper ``gauge`` (default
    :class:`TiltGauge`). One command per pose and one reading per pose and cycle, or a ``ConfigError``."""
    gauge = gauge or TiltGauge()
    source = table.attrs.get("source", "table")
    pairs = [pair for pair in ANGLE_PAIRS if pair[1] in table.columns]
    results = []
    for label, pose, conditions, rows in condition_groups(table):
        _check_constant_command(rows, [c for c, _ in pairs], source)
        _check_unique_cycles(rows, source)
        rows = rows.sort_values("cycle", kind="stable")
        figures = []
        for command, attained in pairs:
            try:
                figures.append(
                    orientation_figures(
                        rows[attained].to_numpy(float), float(rows[command].iloc[0]), gauge, angle=attained[0], k=k
                    )
                )
            except InsufficientData as exc:
                raise InsufficientData(f"{source}: pose {label!r}: {exc}") from None
        results.append(TiltPoseResult(label, pose, conditions, tuple(figures)))
    return results


def tilt_result_json(result: TiltPoseResult) -> dict[str, Any]:
    """One pose's figures as ``bench analyze orientation --json`` prints them (keys carry their units)."""
    out: dict[str, Any] = {"pose": result.pose, **dict(result.conditions)}
    for figures in result.figures:
        entry = figures.as_json()
        out["n"] = entry.pop("n")
        out["k"] = entry.pop("k")
        out[f"budget_{figures.angle}_deg"] = entry.pop("budget_deg")
        out.update(entry)
    return out


def orientation_summary(results: Sequence[TiltPoseResult]) -> dict[str, Any]:
    """Worst |AP| and RP per angle over all poses (with the U of that pose): the headline of an orientation run."""
    summary = {}
    for angle in dict.fromkeys(f.angle for r in results for f in r.figures):
        # in label order, so that a tie names the same pose whatever the order of the table's rows
        rows = [
            (r, f) for r in sorted(results, key=lambda r: natural_key(r.label)) for f in r.figures if f.angle == angle
        ]
        worst_ap = max(rows, key=lambda rf: abs(rf[1].ap_deg))
        worst_rp = max(rows, key=lambda rf: rf[1].rp_deg)
        summary[angle] = {
            "worst_abs_AP_deg": abs(worst_ap[1].ap_deg),
            "U_AP_deg": worst_ap[1].u_ap_deg,
            "worst_AP_pose": worst_ap[0].label,
            "worst_RP_deg": worst_rp[1].rp_deg,
            "U_RP_deg": worst_rp[1].u_rp_deg,
            "worst_RP_pose": worst_rp[0].label,
            "mean_abs_AP_deg": sum(abs(f.ap_deg) for _, f in rows) / len(rows),
            "mean_RP_deg": sum(f.rp_deg for _, f in rows) / len(rows),
        }
    return summary
