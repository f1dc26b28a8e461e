"""Tidy-table interface of the metrology core: read and check sample tables, analyse them per pose.

A pose table has one row per attained sample: ``pose, cycle, cmd_x_mm, cmd_y_mm, cmd_z_mm, x_mm, y_mm, z_mm``,
optionally the angle pairs ``cmd_a_deg/a_deg``, ``cmd_b_deg/b_deg``, ``cmd_c_deg/c_deg``, the conditions
``velocity_pct`` and ``load_kg``, ``t_s``, and a ``frame`` tag (one frame per pose). Poses are labels (P1..P5 or any string); cycle counts may differ
between poses. Results are grouped by pose and, when they vary, by the conditions. Bad cells raise
``ConfigError`` naming the source, the CSV line, the column and the value.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from bench.errors import ConfigError, InsufficientData
from bench.metrology._moments import cycle_moments
from bench.metrology._validation import as_points, as_vector, require_count
from bench.metrology.iso9283 import (
    DistanceCharacteristics,
    OrientationAccuracy,
    OrientationDistanceCharacteristics,
    OrientationRepeatability,
    PoseAccuracy,
    PoseRepeatability,
    distance_characteristics,
    moments_accuracy,
    moments_repeatability,
    orientation_accuracy,
    orientation_distance_characteristics,
    orientation_repeatability,
)
from bench.metrology.table_reading import numeric_columns, read_table_csv
from bench.metrology.uncertainty import (
    Measured,
    expanded,
    moments_ap_uncertainty,
    moments_repeatability_uncertainty,
)

__all__ = [
    "ANGLE_PAIRS",
    "CONDITION_COLUMNS",
    "POSE_COLUMNS",
    "POSE_NUMERIC_COLUMNS",
    "PoseResult",
    "analyze_distance",
    "analyze_orientation_distance",
    "analyze_poses",
    "condition_groups",
    "measured_axes",
    "numeric_columns",
    "pose_result_json",
    "pose_table",
    "read_table_csv",
    "STABILISATION_COLUMNS",
    "with_pose_labels",
]

POSE_COLUMNS = ("pose", "cycle", "cmd_x_mm", "cmd_y_mm", "cmd_z_mm", "x_mm", "y_mm", "z_mm")
ANGLE_PAIRS = (("cmd_a_deg", "a_deg"), ("cmd_b_deg", "b_deg"), ("cmd_c_deg", "c_deg"))
CONDITION_COLUMNS = ("velocity_pct", "load_kg")
#: Columns of a streamed-arrival table (``bench export RUN --series`` of an ``iso9283_stabilisation`` run).
STABILISATION_COLUMNS = ("pose", "cycle", "t_s", "x_mm", "y_mm", "z_mm")
#: Every column `pose_table` turns into numbers (for ``read_table_csv(path, numeric=POSE_NUMERIC_COLUMNS)``).
POSE_NUMERIC_COLUMNS = (*POSE_COLUMNS[1:], *(c for pair in ANGLE_PAIRS for c in pair), *CONDITION_COLUMNS, "t_s")
_COMMAND = ("cmd_x_mm", "cmd_y_mm", "cmd_z_mm")
_ATTAINED = ("x_mm", "y_mm", "z_mm")


@dataclass(frozen=True)
class PoseResult:
    """AP and RP (position and, when measured, orientation) of one pose under one set of conditions."""

    label: str  #: the pose name, followed by the conditions when they vary within the table
    pose: str
    conditions: tuple[tuple[str, float], ...]  #: e.g. (("velocity_pct", 100.0), ("load_kg", 2.0))
    commanded_mm: tuple[float, float, float]
    accuracy: PoseAccuracy
    repeatability: PoseRepeatability
    ap_u: Measured  #: AP_P with its expanded uncertainty
    rp_u: Measured  #: RP_l with a bootstrap expanded uncertainty over cycles
    orientation_accuracy: OrientationAccuracy | None
    orientation_repeatability: OrientationRepeatability | None
    angle_names: tuple[str, ...]  #: which of "a", "b", "c" were measured
    #: the position axes the instrument measured, in x, y, z order; ``accuracy.ap_axes_mm`` and the RP are over
    #: these only (:func:`analyze_poses`; a camera on the x-y plane: ("x", "y"))
    axis_names: tuple[str, ...] = ("x", "y", "z")


def measured_axes(table: pd.DataFrame) -> tuple[str, ...]:
    """The attained position columns of ``table`` (``x_mm``, ``y_mm``, ``z_mm``, in that order) that it has."""
    return tuple(c for c in _ATTAINED if c in table.columns)


def pose_table(frame: pd.DataFrame, *, partial_axes: bool = False) -> pd.DataFrame:
    """Check a pose table and return it with numeric columns as float and ``pose`` as a stripped string.

    A commanded angle with no measured one (a tilted pose measured by the mice, which see position only) leaves the
    position characteristics: that angle is not analysed. A measured angle needs its command (no AP without one).

    ``partial_axes``: the table may lack attained position columns (an instrument that measures a subset of the
    axes: the camera spot sensor reads x, y on its plane and never z); at least one must be there, and
    :func:`analyze_poses` then reports AP/RP over the present ones (:func:`measured_axes`). A missing axis is never
    filled. By default all three are required (the distance, drift and path analyses need them)."""
    source = frame.attrs.get("source", "table")
    if partial_axes and not measured_axes(frame):
        raise ConfigError(
            f"{source}: missing column(s) {', '.join(_ATTAINED)}; found {', '.join(frame.columns)}, "
            "expected at least one measured position axis"
        )
    for command, attained in ANGLE_PAIRS:
        if attained in frame.columns and command not in frame.columns:
            raise ConfigError(f"{source}: column {attained} given without {command}")
    frame = frame.drop(columns=[c for c, a in ANGLE_PAIRS if c in frame.columns and a not in frame.columns])
    if "pose" not in frame.columns:
        raise ConfigError(f"{source}: missing column(s) pose; found {', '.join(frame.columns)}")
    angles = [c for pair in ANGLE_PAIRS for c in pair if c in frame.columns]
    optional = [c for c in (*CONDITION_COLUMNS, "t_s") if c in frame.columns]
    required = [c for c in POSE_COLUMNS[1:] if not (partial_axes and c in _ATTAINED and c not in frame.columns)]
    table = numeric_columns(frame, required)
    table = numeric_columns(table, [*angles, *optional], required=False)
    return with_pose_labels(table, frame, source)


def with_pose_labels(table: pd.DataFrame, frame: pd.DataFrame, source: str) -> pd.DataFrame:
    """``table`` with ``frame``'s pose labels as stripped strings (an empty one refused, naming its row) and its
    ``source`` attribute set."""
    table["pose"] = frame["pose"].astype(str).str.strip()
    empty = table["pose"] == ""
    if empty.any():
        raise ConfigError(f"{source}: row {int(empty.idxmax()) + 1}, column pose: empty, expected a pose label")
    table.attrs["source"] = source
    return table


def condition_groups(
    table: pd.DataFrame,
) -> Iterator[tuple[str, str, tuple[tuple[str, float], ...], pd.DataFrame]]:
    """Yield ``(label, pose, conditions, rows)`` per pose and set of test conditions, in order of appearance.

    The table is split by the condition columns (velocity, load) only where they vary within it; ``label`` is the
    pose, followed by those conditions (``P1 (velocity_pct=50, load_kg=2)``).
    """
    keys = ["pose", *(c for c in CONDITION_COLUMNS if c in table.columns and table[c].nunique() > 1)]
    for key, rows in table.groupby([table["pose"].astype(str), *(table[c] for c in keys[1:])], sort=False):
        key = key if isinstance(key, tuple) else (key,)
        pose, conditions = str(key[0]), tuple((name, float(v)) for name, v in zip(keys[1:], key[1:]))
        label = pose if not conditions else f"{pose} ({', '.join(f'{n}={v:g}' for n, v in conditions)})"
        yield label, pose, conditions, rows


def _check_constant_command(group: pd.DataFrame, columns: Sequence[str], source: str) -> None:
    for column in columns:
        values = group[column].to_numpy()
        differs = np.flatnonzero(values != values[0])
        if len(differs):
            index = group.index[differs[0]]
            raise ConfigError(
                f"{source}: row {int(index) + 1}, column {column}: {values[differs[0]]:g} differs from "
                f"{values[0]:g} earlier in pose {group['pose'].iloc[0]!r}, expected one command per pose"
            )


def _check_single_frame(group: pd.DataFrame, source: str) -> None:
    """Refuse a pose whose samples carry different frame tags (iso9283.md §6.18: never mix frames)."""
    if "frame" not in group.columns:
        return
    frames = group["frame"].astype(str).str.strip()
    differs = np.flatnonzero(frames.to_numpy() != frames.iloc[0])
    if len(differs):
        index = group.index[differs[0]]
        raise ConfigError(
            f"{source}: row {int(index) + 1}, column frame: {frames.iloc[differs[0]]!r} differs from "
            f"{frames.iloc[0]!r} earlier in pose {group['pose'].iloc[0]!r}, expected one frame per pose"
        )


def _check_unique_cycles(group: pd.DataFrame, source: str) -> None:
    duplicated = group["cycle"].duplicated()
    if duplicated.any():
        index = duplicated.idxmax()
        raise ConfigError(
            f"{source}: row {int(index) + 1}, column cycle: cycle {group.at[index, 'cycle']:g} repeated "
            f"for pose {group.at[index, 'pose']!r}, expected one row per pose and cycle"
        )


def _checked_pose_groups(
    table: pd.DataFrame, commands: Sequence[str], source: str
) -> Iterator[tuple[str, str, tuple[tuple[str, float], ...], np.ndarray]]:
    """Yield ``(label, pose, conditions, rows)`` as :func:`condition_groups` does, ``rows`` the group's positions in
    ``table`` in cycle order, after the checks of every group (one command, one frame, one row per cycle).

    The checks run on whole columns at once (a table of 10^7 rows in 100 poses: no per-group frames); when one
    fails, the group-by-group checks run to raise the message they always gave (the first group and row at fault).
    """
    keys = [c for c in CONDITION_COLUMNS if c in table.columns and table[c].nunique() > 1]
    if keys:
        codes = table.groupby([table["pose"].astype(str), *(table[c] for c in keys)], sort=False).ngroup().to_numpy()
    else:
        codes = pd.factorize(table["pose"].astype(str))[0]
    # a stable sort by group keeps each group's rows in table order; int16 codes sort by radix, in linear time
    codes = codes.astype(np.int16 if codes.max(initial=0) < 2**15 else np.int64)
    order = np.argsort(codes, kind="stable")
    grouped, cycles = codes[order], table["cycle"].to_numpy(float)[order]
    same_group = grouped[1:] == grouped[:-1]
    if not np.all(cycles[1:][same_group] > cycles[:-1][same_group]):  # not in cycle order yet (or a cycle repeated)
        order = np.lexsort((table["cycle"].to_numpy(float), codes))
        cycles = table["cycle"].to_numpy(float)[order]
    starts = np.flatnonzero(np.r_[True, grouped[1:] != grouped[:-1]])
    first_rows = order[starts]  # per group code (0, 1, .. in order of appearance): its first row in the table
    checked = [table[c].to_numpy(float) for c in commands]
    if "frame" in table.columns:
        checked.append(pd.factorize(table["frame"].astype(str).str.strip())[0])
    if np.any(cycles[1:][same_group] == cycles[:-1][same_group]) or any(
        np.any(values != values[first_rows][codes]) for values in checked
    ):
        for _, _, _, group in condition_groups(table):  # the message of the first group and row at fault
            _check_constant_command(group, commands, source)
            _check_single_frame(group, source)
            _check_unique_cycles(group, source)
    # the labels: a string per group only, fetched at once (a cell fetch from pandas costs ~10 us)
    poses = [str(pose) for pose in table["pose"].iloc[order[starts]]]
    key_values = [table[c].to_numpy() for c in keys]
    for pose, rows in zip(poses, np.split(order, starts[1:])):
        conditions = tuple((c, float(v[rows[0]])) for c, v in zip(keys, key_values))
        label = pose if not conditions else f"{pose} ({', '.join(f'{n}={v:g}' for n, v in conditions)})"
        yield label, pose, conditions, rows


def analyze_poses(
    table: pd.DataFrame, *, instrument_u_mm: float = 0.0, k: float = 2.0, resamples: int = 1000
) -> list[PoseResult]:
    """AP, RP and their expanded uncertainties for every pose (and set of conditions) of a pose table.

    Over the measured position axes (:func:`measured_axes`; all three for a table from :func:`pose_table` without
    ``partial_axes``). For an instrument that reads a subset (the camera: x, y), the ISO 9283 formulas restricted
    to those axes: 7.2.1 AP components x̄ - x_c, ȳ - y_c on the measured axes and AP_P = sqrt of the sum of their
    squares (the distance in the measured plane); 7.2.2 RP_l = l̄ + 3 S_l with l_j the distance of reading j from
    the barycentre over the measured axes. These are not the 3-D figures (an unmeasured axis adds to both) and
    carry ``axis_names`` so that every table says so.

    Parameters
    ----------
    table : DataFrame
        Output of `pose_table`.
    instrument_u_mm : float
        Standard uncertainty of the instrument per axis (systematic and registration), added to the AP budget.
    k : float
        Coverage factor of the reported expanded uncertainties.
    resamples : int
        Bootstrap resamples of ``repeatability_uncertainty(method="bootstrap")``; the default U(RP) (a measurement-model
        Monte Carlo up to 100 cycles, the delta method above) does not resample.

    Raises
    ------
    InsufficientData
        A pose with fewer than 2 cycles (named in the message).
    """
    source = table.attrs.get("source", "table")
    angles = [(cmd, att) for cmd, att in ANGLE_PAIRS if cmd in table.columns]
    axes = measured_axes(table)
    columns = {c: table[c].to_numpy(float) for c in (*axes, *_COMMAND, *(c for pair in angles for c in pair))}
    results = []
    for label, pose, conditions, rows in _checked_pose_groups(table, [*_COMMAND, *(c for c, _ in angles)], source):
        # column-major, as a frame's block: each axis contiguous (and the sums in the order they always had)
        attained = np.array([columns[c][rows] for c in axes]).T
        attained_deg = np.array([columns[att][rows] for _, att in angles]).T if angles else None
        commands = {c: float(columns[c][rows[0]]) for c in (*_COMMAND, *(cmd for cmd, _ in angles))}
        group = PoseGroup(label, pose, conditions, axes, attained, angles, attained_deg, commands)
        results.append(pose_result(group, source=source, instrument_u_mm=instrument_u_mm, k=k, resamples=resamples))
    return results


@dataclass(frozen=True, eq=False)
class PoseGroup:
    """The checked samples of one pose (and set of conditions), in cycle order, as :func:`pose_result` takes them."""

    label: str
    pose: str
    conditions: tuple[tuple[str, float], ...]
    axes: tuple[str, ...]  #: the measured position columns (``x_mm``.. in x, y, z order)
    attained: np.ndarray  #: (n, len(axes)) mm, column-major
    angles: list[tuple[str, str]]  #: the (commanded, attained) angle column pairs
    attained_deg: np.ndarray | None  #: (n, len(angles)) degrees
    commands: dict[str, float]  #: the pose's command per column (cmd_x_mm.., cmd_a_deg..)


def pose_result(group: PoseGroup, *, source: str, instrument_u_mm: float, k: float, resamples: int) -> PoseResult:
    """AP, RP, their uncertainties and the orientation figures of one checked pose group (:func:`analyze_poses`)."""
    full_command = np.array([group.commands[c] for c in _COMMAND])
    command = full_command[[_ATTAINED.index(c) for c in group.axes]]
    # checked once, then the figures share the cycles' moments (the public functions check their own inputs)
    attained = as_points("attained_mm", group.attained)
    try:
        require_count("pose repeatability cycles", len(attained), 2)
    except InsufficientData as exc:
        raise type(exc)(f"{source}: pose {group.label!r}: {exc}") from None
    command = as_vector("commanded_mm", command, length=attained.shape[1])
    moments = cycle_moments(attained)
    repeatability = moments_repeatability(moments)
    ap_u = moments_ap_uncertainty(moments, command, instrument_u_mm=instrument_u_mm, k=k)
    u_rp = moments_repeatability_uncertainty(moments, repeatability.rp_mm) if len(attained) >= 3 else 0.0
    orientation = None
    if group.attained_deg is not None:
        orientation = (
            orientation_accuracy(group.attained_deg, np.array([group.commands[cmd] for cmd, _ in group.angles])),
            orientation_repeatability(group.attained_deg),
        )
    return PoseResult(
        label=group.label,
        pose=group.pose,
        conditions=group.conditions,
        commanded_mm=(float(full_command[0]), float(full_command[1]), float(full_command[2])),
        accuracy=moments_accuracy(moments, command),
        repeatability=repeatability,
        ap_u=ap_u,
        rp_u=expanded(repeatability.rp_mm, u_rp, unit="mm", k=k),
        orientation_accuracy=orientation[0] if orientation else None,
        orientation_repeatability=orientation[1] if orientation else None,
        angle_names=tuple(att[0] for _, att in group.angles),
        axis_names=tuple(c[0] for c in group.axes),
    )


def pose_result_json(result: PoseResult) -> dict[str, Any]:
    """The JSON object of one pose for ``bench analyze iso9283 --json``."""
    ax, ay, az = (dict(zip(result.axis_names, result.accuracy.ap_axes_mm)).get(a) for a in "xyz")  # None: not measured
    out: dict[str, Any] = {
        "n": result.accuracy.n,
        "AP_mm": result.accuracy.ap_mm,
        "APx_mm": ax,
        "APy_mm": ay,
        "APz_mm": az,
        "RP_mm": result.repeatability.rp_mm,
        "barycentre_mm": list(result.accuracy.barycentre_mm),
        "commanded_mm": list(result.commanded_mm),
        "U_AP_mm": result.ap_u.expanded_uncertainty,
        "U_RP_mm": result.rp_u.expanded_uncertainty,
        "k": result.ap_u.coverage_factor,
    }
    if result.axis_names != ("x", "y", "z"):
        out["measured_axes"] = list(result.axis_names)
    if result.orientation_accuracy is not None and result.orientation_repeatability is not None:
        for name, ap, rp in zip(
            result.angle_names, result.orientation_accuracy.ap_deg, result.orientation_repeatability.rp_deg
        ):
            out[f"AP{name}_deg"] = ap
            out[f"RP{name}_deg"] = rp
    if result.conditions:
        out["pose"] = result.pose
        out.update(dict(result.conditions))
    return out


def _paired_by_cycle(
    table: pd.DataFrame, first_pose: str, second_pose: str
) -> tuple[pd.DataFrame, pd.DataFrame, list[Any]]:
    """The rows of two poses indexed by cycle, and the cycles they share (all of them, or a ConfigError)."""
    source = table.attrs.get("source", "table")
    groups = {}
    for pose in (first_pose, second_pose):
        rows = table[table["pose"] == pose]
        if rows.empty:
            raise ConfigError(f"{source}: pose {pose!r} not found; poses: {', '.join(table['pose'].unique())}")
        _check_constant_command(rows, _COMMAND, source)
        _check_single_frame(rows, source)
        _check_unique_cycles(rows, source)
        groups[pose] = rows.set_index("cycle")
    first, second = groups[first_pose], groups[second_pose]
    unpaired = sorted(set(first.index) ^ set(second.index))
    if unpaired:
        raise ConfigError(
            f"{source}: cycle(s) {', '.join(f'{c:g}' for c in unpaired[:5])} present at only one of "
            f"{first_pose!r} and {second_pose!r}, expected paired cycles"
        )
    return first, second, sorted(first.index)


def analyze_distance(table: pd.DataFrame, first_pose: str, second_pose: str) -> DistanceCharacteristics:
    """AD and RD between two poses of a pose table, pairing the samples by cycle (ISO 9283 7.3).

    Cycles present at only one of the two poses are refused with a message naming them.
    """
    first, second, cycles = _paired_by_cycle(table, first_pose, second_pose)
    return distance_characteristics(
        first.loc[cycles, list(_ATTAINED)].to_numpy(),
        second.loc[cycles, list(_ATTAINED)].to_numpy(),
        first[list(_COMMAND)].to_numpy()[0],
        second[list(_COMMAND)].to_numpy()[0],
    )


def analyze_orientation_distance(
    table: pd.DataFrame, first_pose: str, second_pose: str
) -> tuple[tuple[str, ...], OrientationDistanceCharacteristics] | None:
    """AD_a/b/c and RD_a/b/c between two poses, paired by cycle (ISO 9283 7.3), for the angles the table has:
    ``(("a", "b"), result)``, or None without angle columns."""
    pairs = [(c, a) for c, a in ANGLE_PAIRS if a in table.columns]
    if not pairs:
        return None
    first, second, cycles = _paired_by_cycle(table, first_pose, second_pose)
    commanded, attained = [c for c, _ in pairs], [a for _, a in pairs]
    source = table.attrs.get("source", "table")
    for rows in (first, second):
        _check_constant_command(rows.reset_index(), commanded, source)
    return tuple(a[0] for a in attained), orientation_distance_characteristics(
        first.loc[cycles, attained].to_numpy(),
        second.loc[cycles, attained].to_numpy(),
        first[commanded].to_numpy()[0],
        second[commanded].to_numpy()[0],
    )
