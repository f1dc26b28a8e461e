"""Actuator travel tables (one row per reading) to per-actuator figures: the one path that ``bench analyze actuator``
and the actuator report share, so a report number equals the command's number on the same CSV by construction.

A table has ``actuator``, the commanded travel ``cmd_mm`` (hand-made tables, e.g. ``examples/data``) or
``cmd_travel_mm`` (``bench export RUN --kind actuator_travel`` of an ``actuator_accuracy`` run), the reading
``travel_mm``, optionally ``cr_mm`` (control resolution per row) and a repeat number ``cycle`` or ``repeat``.
Figures per actuator: Groover repeatability/accuracy and the mean bias per target
(:func:`~bench.metrology.actuator.groover_actuator`, dissertation Eqs. 8.1-8.3), the unidirectional ISO 230-2
figures (:func:`~bench.metrology.actuator.positioning_iso230_2`; every approach is from below), and expanded
uncertainties:

- bias per target: U = k·√(s_i²/n + u_instrument²) (scatter of the mean and the gauge);
- Groover repeatability 3σ̄ (and accuracy CR/2 + 3σ̄, CR exact): a Monte Carlo of the measurement model
  (:func:`bench.metrology.uncertainty.mean_sd_uncertainty`, small-sample bias included; the bootstrap it replaces
  covered 86 % at n = 10); none with fewer than 3 repeats.

A ``direction`` column (a bidirectional run, ISO 230-2: +1 approached from below, -1 from above) keeps the
readings approached from below for these figures, the dissertation's approach; the bidirectional figures are
:func:`bench.metrology.bidirectional_tables.analyze_bidirectional`'s. With a repeat column, readings are paired by
repeat and repeats missing a target are left out (counted in
``dropped``); without one, every target must have the same number of readings (paired in row order).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from bench.errors import ConfigError, InsufficientData
from bench.metrology.actuator import (
    GrooverActuator,
    PositioningIso2302,
    groover_actuator,
    positioning_iso230_2,
)
from bench.metrology.tables import numeric_columns
from bench.metrology.uncertainty import Measured, combine, expanded, mean_sd_uncertainty

__all__ = [
    "ACTUATOR_ROBOTS",
    "COMMAND_COLUMNS",
    "REPEAT_COLUMNS",
    "ActuatorResult",
    "actuator_table",
    "analyze_actuators",
    "robot_control_resolution",
]

#: Accepted names of the commanded-travel column, in order of preference.
COMMAND_COLUMNS = ("cmd_mm", "cmd_travel_mm")
#: Accepted names of the repeat column.
REPEAT_COLUMNS = ("cycle", "repeat")
#: Robots whose actuator numbers map to a control resolution (:func:`robot_control_resolution`).
ACTUATOR_ROBOTS = ("pkm5",)


@dataclass(frozen=True, eq=False)
class ActuatorResult:
    """Every figure of one actuator, with the readings it was computed from."""

    actuator: str
    targets_mm: tuple[float, ...]
    readings_mm: np.ndarray  #: (n repeats, m targets), mm
    control_resolution_mm: float
    groover: GrooverActuator
    iso230_2: PositioningIso2302  #: unidirectional (↑) figures only
    bias_u: tuple[Measured, ...]  #: signed x̄_i - P_i per target with U
    repeatability_u: Measured | None  #: 3σ̄ with a bootstrap U over repeats (None below 3 repeats)
    accuracy_u: Measured | None  #: CR/2 + 3σ̄ with the same U
    dropped: int = 0  #: readings left out because their repeat misses a target


def robot_control_resolution(robot: str) -> tuple[float, ...]:
    """Control resolution CR (mm/step) per actuator number (1-based) of ``robot``'s kinematic model: for the pkm5
    the leg-length change per step (000 Eq. 8.1), ``motion.pkm5.DEFAULT_GEOMETRY.mm_per_step``. The one lookup of
    ``bench analyze actuator --robot``, the actuator report and the protocol's own reduction.

    Examples
    --------
    >>> robot_control_resolution("pkm5")  # 1.25 mm lead over 200 full steps per rev, 400 for actuators 5-6
    (0.00625, 0.00625, 0.00625, 0.00625, 0.003125, 0.003125)
    """
    if robot not in ACTUATOR_ROBOTS:
        raise ConfigError(f"robot {robot!r}: no actuator model, expected one of {', '.join(ACTUATOR_ROBOTS)}")
    from motion import pkm5  # pure kinematics, imported only when asked

    return tuple(float(v) for v in pkm5.DEFAULT_GEOMETRY.mm_per_step)


def actuator_table(frame: pd.DataFrame) -> pd.DataFrame:
    """Check an actuator travel table; return it with ``cmd_mm``, ``travel_mm`` (and ``cr_mm``, the repeat column)
    as float and ``actuator`` as a stripped string. ``cmd_travel_mm`` (an exported run) is read as ``cmd_mm``."""
    source = frame.attrs.get("source", "table")
    command = next((c for c in COMMAND_COLUMNS if c in frame.columns), None)
    missing = [
        name
        for name, ok in (
            ("actuator", "actuator" in frame.columns),
            ("travel_mm", "travel_mm" in frame.columns),
            (" or ".join(COMMAND_COLUMNS), command is not None),
        )
        if not ok
    ]
    if missing:
        raise ConfigError(f"{source}: missing column(s) {', '.join(missing)}; found {', '.join(frame.columns)}")
    assert command is not None  # a missing command column was refused above
    optional = [c for c in ("cr_mm", *REPEAT_COLUMNS) if c in frame.columns]
    table = numeric_columns(frame, [command, "travel_mm", *optional])
    if command != "cmd_mm":
        table = table.drop(columns=["cmd_mm"], errors="ignore").rename(columns={command: "cmd_mm"})
    table["actuator"] = frame["actuator"].astype(str).str.strip()
    if "direction" in table.columns:  # bidirectional: the approaches from below (module docstring)
        from bench.metrology.bidirectional_tables import approach_directions

        direction = approach_directions(frame["direction"])
        if direction.isna().any():
            index = direction.isna().idxmax()
            raise ConfigError(
                f"{source}: row {int(index) + 1}, column direction: {frame.at[index, 'direction']!r}, "
                "expected up or down (+/-, +1/-1)"
            )
        table = table[direction == "up"].drop(columns=["direction"])
    table.attrs["source"] = source
    return table


def _resolution(rows: pd.DataFrame, name: str, given: Any, source: str) -> float:
    if "cr_mm" in rows.columns:
        return float(rows["cr_mm"].iloc[0])
    if given is None:
        raise ConfigError(f"{source}: no cr_mm column and no control resolution given, expected one of them")
    if np.ndim(given) == 1:  # per actuator number, 1-based (a robot's mm per step)
        try:
            number = float(name)
        except ValueError:
            number = 0.0
        if number != int(number) or not 1 <= number <= len(given):
            raise ConfigError(
                f"{source}: actuator {name!r}: no control resolution for it, expected an actuator number 1-{len(given)}"
            )
        return float(given[int(number) - 1])
    return float(given)


def _readings(rows: pd.DataFrame, name: str, source: str) -> tuple[np.ndarray, np.ndarray, int]:
    """(targets, readings (n, m), readings dropped) of one actuator."""
    targets = np.unique(rows["cmd_mm"].to_numpy())
    repeat = next((c for c in REPEAT_COLUMNS if c in rows.columns), None)
    if repeat is None:
        counts = {float(t): int((rows["cmd_mm"] == t).sum()) for t in targets}
        if len(set(counts.values())) != 1:
            raise ConfigError(
                f"{source}: actuator {name}: repeats per target {counts}, expected equal counts "
                f"(or a {' or '.join(REPEAT_COLUMNS)} column to pair the readings)"
            )
        readings = np.column_stack([rows.loc[rows["cmd_mm"] == t, "travel_mm"].to_numpy() for t in targets])
        return targets, readings, 0
    doubled = rows.duplicated([repeat, "cmd_mm"])
    if doubled.any():
        row = rows[doubled].iloc[0]
        raise ConfigError(
            f"{source}: actuator {name}: two readings for {repeat} {row[repeat]:g} at "
            f"{row['cmd_mm']:g} mm, expected one"
        )
    wide = rows.pivot(index=repeat, columns="cmd_mm", values="travel_mm").sort_index()
    complete = wide.dropna()
    return targets, complete[targets].to_numpy(), int(wide.notna().sum().sum() - complete.size)


def analyze_actuators(
    table: pd.DataFrame,
    *,
    control_resolution_mm: float | Sequence[float] | None = None,
    instrument_u_mm: float = 0.0,
    k: float = 2.0,
) -> tuple[ActuatorResult, ...]:
    """Figures of every actuator of a checked table (:func:`actuator_table`), in order of appearance.

    Parameters
    ----------
    table : DataFrame
    control_resolution_mm : float or sequence, optional
        CR when the table has no ``cr_mm`` column: one value for all, or one per actuator number (1-based, e.g. a
        robot's mm per step).
    instrument_u_mm : float
        Standard uncertainty of one travel reading (mm).
    k : float
        Coverage factor of every expanded uncertainty.

    Raises
    ------
    InsufficientData
        An actuator with fewer than 2 complete repeats.
    """
    source = table.attrs.get("source", "table")
    results = []
    for name, rows in table.groupby("actuator", sort=False):
        targets, readings, dropped = _readings(rows, name, source)
        if len(readings) < 2:
            raise InsufficientData(
                f"{source}: actuator {name}: {len(readings)} complete repeat(s) over the targets "
                f"{', '.join(f'{t:g}' for t in targets)} mm, at least 2 required"
            )
        cr = _resolution(rows, name, control_resolution_mm, source)
        groover = groover_actuator(targets, readings, control_resolution_mm=cr)
        bias_u = tuple(
            expanded(b, combine(s / np.sqrt(groover.n), instrument_u_mm), unit="mm", k=k)
            for b, s in zip(groover.mean_deviation_mm, groover.sigma_mm)
        )
        repeatability_u = accuracy_u = None
        if len(readings) >= 3:
            u = 3.0 * mean_sd_uncertainty(readings, k=k)
            repeatability_u = expanded(groover.repeatability_mm, u, unit="mm", k=k)
            accuracy_u = expanded(groover.accuracy_mm, u, unit="mm", k=k)
        results.append(
            ActuatorResult(
                str(name),
                tuple(float(t) for t in targets),
                readings,
                cr,
                groover,
                positioning_iso230_2(targets, readings),
                bias_u,
                repeatability_u,
                accuracy_u,
                dropped,
            )
        )
    if not results:
        raise InsufficientData(f"{source}: no actuator readings")
    return tuple(results)
