"""Tidy tables of tilt readings -> orientation AP/RP per pose (ISO 9283 7.2.1, 7.2.2) with the calliper budget.

The table is what ``bench export RUN --kind tilt`` writes for a ``dissertation_pose`` alpha/beta run: ``pose``,
``cycle``, ``cmd_a_deg``/``a_deg`` (alpha) or ``cmd_b_deg``/``b_deg`` (beta), and the condition columns. A pose
table that also has positions (``x_mm`` ...) is read the same way; its positions are ignored here. Row order
carries no meaning: each pose's readings are taken in cycle order.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

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
)

__all__ = ["TILT_NUMERIC_COLUMNS", "TiltPoseResult", "analyze_tilts", "orientation_summary", "tilt_result_json",
           "tilt_table"]

#: Columns a tilt table's reader turns into numbers.
TILT_NUMERIC_COLUMNS = ("cycle", *(c for pair in ANGLE_PAIRS for c in pair), *CONDITION_COLUMNS)


@dataclass(frozen=True)
class TiltPoseResult:
    """Orientation figures of one pose under one set of conditions, one entry per measured angle."""

    label: str
    pose: str
    conditions: tuple[tuple[str, float], ...]
    figures: tuple[OrientationFigures, ...]


def tilt_table(frame: pd.DataFrame) -> pd.DataFrame:
    """Check a table of tilt readings; return it with numbers as float and ``pose`` as a stripped string.

    Needs ``pose``, ``cycle`` and at least one measured angle with its command (``a_deg`` with ``cmd_a_deg`` ...);
    a measured angle without its command, or a table without any angle, is a one-line ``ConfigError``.
    """
    source = frame.attrs.get("source", "table")
    missing = [c for c in ("pose", "cycle") if c not in frame.columns]
    if missing:
        raise ConfigError(f"{source}: missing column(s) {', '.join(missing)}; found {', '.join(frame.columns)}")
    for command, attained in ANGLE_PAIRS:
        if attained in frame.columns and command not in frame.columns:
            raise ConfigError(f"{source}: column {attained} given without {command}")
    pairs = [pair for pair in ANGLE_PAIRS if pair[1] in frame.columns]
    if not pairs:
        raise ConfigError(f"{source}: no measured angle (a_deg, b_deg or c_deg with cmd_a_deg ...), expected the "
                          f"tilt readings of an alpha or beta run (bench export RUN --kind tilt)")
    columns = ["pose", "cycle", *(c for pair in pairs for c in pair),
               *(c for c in CONDITION_COLUMNS if c in frame.columns)]
    table = numeric_columns(frame[columns], columns[1:])
    table["pose"] = frame["pose"].astype(str).str.strip()
    empty = table["pose"] == ""
    if empty.any():
        raise ConfigError(f"{source}: row {int(empty.idxmax()) + 1}, column pose: empty, expected a pose label")
    table.attrs["source"] = source
    return table


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
                figures.append(orientation_figures(rows[attained].to_numpy(float), float(rows[command].iloc[0]),
                                                   gauge, angle=attained[0], k=k))
            except InsufficientData as exc:
                raise InsufficientData(f"{source}: pose {label!r}: {exc}") from None
        results.append(TiltPoseResult(label, pose, conditions, tuple(figures)))
    return results


def tilt_result_json(result: TiltPoseResult) -> dict:
    """One pose's figures as ``bench analyze orientation --json`` prints them (keys carry their units)."""
    out: dict = {"pose": result.pose, **dict(result.conditions)}
    for figures in result.figures:
        entry = figures.as_json()
        out["n"] = entry.pop("n")
        out["k"] = entry.pop("k")
        out[f"budget_{figures.angle}_deg"] = entry.pop("budget_deg")
        out.update(entry)
    return out


def orientation_summary(results: Sequence[TiltPoseResult]) -> dict:
    """Worst |AP| and RP per angle over all poses (with the U of that pose): the headline of an orientation run."""
    summary = {}
    for angle in dict.fromkeys(f.angle for r in results for f in r.figures):
        # in label order, so that a tie names the same pose whatever the order of the table's rows
        rows = [(r, f) for r in sorted(results, key=lambda r: natural_key(r.label)) for f in r.figures
                if f.angle == angle]
        worst_ap = max(rows, key=lambda rf: abs(rf[1].ap_deg))
        worst_rp = max(rows, key=lambda rf: rf[1].rp_deg)
        summary[angle] = {"worst_abs_AP_deg": abs(worst_ap[1].ap_deg), "U_AP_deg": worst_ap[1].u_ap_deg,
                          "worst_AP_pose": worst_ap[0].label, "worst_RP_deg": worst_rp[1].rp_deg,
                          "U_RP_deg": worst_rp[1].u_rp_deg, "worst_RP_pose": worst_rp[0].label,
                          "mean_abs_AP_deg": sum(abs(f.ap_deg) for _, f in rows) / len(rows),
                          "mean_RP_deg": sum(f.rp_deg for _, f in rows) / len(rows)}
    return summary
