"""Streamed-arrival tables (``bench export RUN --series`` of an ``iso9283_stabilisation`` run) and their
stabilisation figures per limit band and pose: the one grouping that ``bench analyze stabilisation`` and the
stabilisation report share. Split out of ``tables`` (issue 35: one job per module).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from bench.errors import ConfigError, InsufficientData
from bench.metrology.iso9283_dynamics import PoseStabilisation, pose_stabilisation
from bench.metrology.table_reading import numeric_columns
from bench.metrology.tables import CONDITION_COLUMNS, STABILISATION_COLUMNS, condition_groups

__all__ = ["StabilisationResults", "stabilisation_results", "stabilisation_table"]


@dataclass(frozen=True, eq=False)
class StabilisationResults:
    """The arrivals of a streamed-arrival table and their stabilisation figures.

    ``series`` holds per group label (the pose, with the conditions when they vary, as :func:`condition_groups`
    names it) the ``(cycle, t_s, position_mm)`` of every arrival in cycle order; ``bands`` per limit band and group
    label the :class:`~bench.metrology.iso9283_dynamics.PoseStabilisation`, or the message of the
    ``InsufficientData`` that left it without one (an arrival never entered, or never settled in, the band).
    """

    series: dict[str, tuple[tuple[int, np.ndarray, np.ndarray], ...]]
    bands: dict[float, dict[str, PoseStabilisation | str]]


def stabilisation_table(frame: pd.DataFrame) -> pd.DataFrame:
    """Check a streamed-arrival table; return it sorted by cycle and time, with ``cycle``, ``t_s``,
    ``x_mm``..``z_mm`` (and the condition columns) as float and ``pose`` as a stripped string. A missing column says how to export one; a cell that is
    not a number is a ``ConfigError`` naming its row, column and value."""
    source = frame.attrs.get("source", "table")
    missing = [c for c in STABILISATION_COLUMNS if c not in frame.columns]
    if missing:
        raise ConfigError(f"{source}: missing column(s) {', '.join(missing)}; export the run with --series")
    table = numeric_columns(frame, STABILISATION_COLUMNS[1:])
    table = numeric_columns(table, CONDITION_COLUMNS, required=False)
    table["pose"] = frame["pose"].astype(str).str.strip()
    table.attrs["source"] = source
    # row order carries no meaning: each arrival is read in time order (a repeated time is refused downstream)
    return table.sort_values(["cycle", "t_s"], kind="stable")


def stabilisation_results(table: pd.DataFrame, bands_mm: Sequence[float], hysteresis_mm: float) -> StabilisationResults:
    """Stabilisation time and overshoot per limit band and per pose (and condition) of a checked streamed-arrival
    table (:func:`stabilisation_table`): the arrivals of each group, one per cycle, through
    :func:`~bench.metrology.iso9283_dynamics.pose_stabilisation`. The one grouping that ``bench analyze
    stabilisation`` and the stabilisation report share.
    """
    series = {
        label: tuple(
            (int(cycle), arrival["t_s"].to_numpy(float), arrival[list(STABILISATION_COLUMNS[3:])].to_numpy(float))
            for cycle, arrival in rows.groupby("cycle", sort=True)
        )
        for label, _, _, rows in condition_groups(table)
    }
    bands: dict[float, dict[str, PoseStabilisation | str]] = {}
    for band in bands_mm:
        per_group = bands[float(band)] = {}
        for label, arrivals in series.items():
            try:
                per_group[label] = pose_stabilisation(
                    [(t, p) for _, t, p in arrivals], band_mm=band, hysteresis_mm=hysteresis_mm
                )
            except InsufficientData as exc:
                per_group[label] = str(exc)
    return StabilisationResults(series, bands)
