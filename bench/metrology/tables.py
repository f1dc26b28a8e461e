"""Tidy-table interface of the metrology core: read and check sample tables, analyse them per pose.

A pose table has one row per attained sample: ``pose, cycle, cmd_x_mm, cmd_y_mm, cmd_z_mm, x_mm, y_mm, z_mm``,
optionally the angle pairs ``cmd_a_deg/a_deg``, ``cmd_b_deg/b_deg``, ``cmd_c_deg/c_deg``, the conditions
``velocity_pct`` and ``load_kg``, ``t_s``, and a ``frame`` tag (one frame per pose). Poses are labels (P1..P5 or any string); cycle counts may differ
between poses. Results are grouped by pose and, when they vary, by the conditions. Bad cells raise
``ConfigError`` naming the source, the CSV line, the column and the value.
"""

from __future__ import annotations

import codecs
import csv
import io
import re
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from bench.errors import ConfigError, InsufficientData
from bench.metrology.iso9283 import (
    DistanceCharacteristics,
    OrientationAccuracy,
    OrientationDistanceCharacteristics,
    OrientationRepeatability,
    PoseAccuracy,
    PoseRepeatability,
    distance_characteristics,
    orientation_accuracy,
    orientation_distance_characteristics,
    orientation_repeatability,
    pose_accuracy,
    pose_repeatability,
)
from bench.metrology.iso9283_dynamics import PoseStabilisation, pose_stabilisation
from bench.metrology.uncertainty import (
    Measured,
    accuracy_uncertainty,
    expanded,
    repeatability_uncertainty,
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
    "StabilisationResults",
    "stabilisation_results",
    "stabilisation_table",
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


def read_table_csv(path: str | Path, *, numeric: Sequence[str] = ()) -> pd.DataFrame:
    """Read a CSV as strings (no type guessing); lines starting with ``#`` and blank lines are skipped.

    Data rows are numbered from 1 after the header, the numbering every error message uses. A missing file, an
    empty table, a repeated column name or a row with the wrong number of fields is a one-line ``ConfigError``.

    ``numeric``: columns to read as float64 at once (those present; the others stay strings), which is what
    :func:`numeric_columns` makes of them anyway: a table of 10^6 rows then never holds millions of strings. A file
    without quotes whose every line has the header's number of fields is parsed by pandas' C reader; anything else
    (quotes, blank lines, a bad row, a cell that is not a number) by the row-by-row reader below, which names the
    row and column at fault.
    """
    path = Path(path)
    try:
        frame = _read_regular_csv(path, numeric) if numeric else None
        if frame is None:
            return _read_csv_rows(path, path.read_bytes())
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such file") from None
    except OSError as exc:
        raise ConfigError(f"{path}: not a readable CSV table ({exc})") from None
    frame.attrs["source"] = str(path)
    return frame


#: Bytes read at a time by the scan that decides between the readers (a bound on its memory).
_SCAN_BYTES = 1 << 24
#: A comment line of a CSV table: optional blanks, then ``#`` (a ``#`` inside a cell is data).
_COMMENT_LINE = re.compile(rb"(?m)^[ \t]*#[^\n]*(?:\n|$)")


def _scan(path: Path) -> tuple[bool, bool]:
    """Whether the file holds a ``"`` (quoting) and a ``#`` (maybe comment lines), scanned a block at a time."""
    quotes = hashes = False
    with path.open("rb") as handle:
        while block := handle.read(_SCAN_BYTES):
            quotes, hashes = quotes or b'"' in block, hashes or b"#" in block
            if quotes:
                break
    return quotes, hashes


def _read_regular_csv(path: Path, numeric: Sequence[str]) -> pd.DataFrame | None:
    """The fast path of `read_table_csv`: pandas' C reader, straight from the file (no copy of it in memory;
    a file with comment lines is read, stripped of them, and parsed from memory), or ``None`` when the file needs
    the row-by-row reader (quotes, a blank or odd header, a row with too many or too few fields, a cell that is not
    a number, bad bytes), which names the row and column at fault."""
    quotes, hashes = _scan(path)
    if quotes:
        return None
    source: Path | io.BytesIO = path
    if hashes:
        source = io.BytesIO(_COMMENT_LINE.sub(b"", path.read_bytes().removeprefix(codecs.BOM_UTF8)))
    with open(source, "rb") if isinstance(source, Path) else source as handle:
        first = handle.readline().removeprefix(codecs.BOM_UTF8)
        handle.seek(0)
        try:
            header = [name.strip() for name in next(csv.reader([first.decode("utf-8")], skipinitialspace=True))]
        except (UnicodeDecodeError, StopIteration):
            return None
        if len(set(header)) != len(header) or "" in header:
            return None
        types = {column: np.float64 for column in numeric if column in header}
        types.update({column: str for column in header if column not in types})
        try:
            with warnings.catch_warnings():  # pandas drops a first row's extra fields with a warning: refused
                warnings.simplefilter("error", pd.errors.ParserWarning)
                frame = pd.read_csv(
                    handle,
                    header=0,
                    names=header,
                    dtype=types,
                    keep_default_na=False,
                    na_values=[],
                    skipinitialspace=True,
                    index_col=False,
                    engine="c",
                    encoding="utf-8",
                )
        except (ValueError, UnicodeDecodeError, pd.errors.ParserError, pd.errors.ParserWarning):
            return None  # a cell that is not a number, bad bytes, a row with too many fields
    if frame.empty or any(frame[column].isna().any() for column in header):
        return None  # a short row (pandas fills it) or a "nan" cell: the row-by-row reader names it
    return frame


def _read_csv_rows(path: Path, data: bytes) -> pd.DataFrame:
    """`read_table_csv` row by row with the csv module: every cell a string, every fault named."""
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: not a readable CSV table ({exc})") from None
    lines = [line for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")]
    rows = list(csv.reader(lines, skipinitialspace=True))
    if not rows:
        raise ConfigError(f"{path}: not a readable CSV table (no header line)")
    header = [name.strip() for name in rows[0]]
    if len(set(header)) != len(header) or "" in header:
        raise ConfigError(f"{path}: header {', '.join(header)}: expected unique, non-empty column names")
    for number, row in enumerate(rows[1:], start=1):
        if len(row) != len(header):
            raise ConfigError(f"{path}: row {number}: {len(row)} fields, expected {len(header)} as in the header")
    frame = pd.DataFrame(rows[1:], columns=header, dtype=str)
    frame.attrs["source"] = str(path)
    return frame


def numeric_columns(frame: pd.DataFrame, columns: Sequence[str], *, required: bool = True) -> pd.DataFrame:
    """Convert ``columns`` to float, naming the line, column and value of the first cell that is not a number.

    Missing columns raise ``ConfigError`` when ``required``; otherwise they are skipped.
    """
    source = frame.attrs.get("source", "table")
    missing = [c for c in columns if c not in frame.columns]
    if missing and required:
        raise ConfigError(f"{source}: missing column(s) {', '.join(missing)}; found {', '.join(frame.columns)}")
    out = frame.copy()
    for column in (c for c in columns if c in frame.columns):
        if pd.api.types.is_float_dtype(frame[column]):  # read as numbers already (read_table_csv's numeric=)
            finite = np.isfinite(frame[column].to_numpy())
            if not finite.all():
                index = frame.index[int(np.argmin(finite))]
                raise ConfigError(
                    f"{source}: row {int(index) + 1}, column {column}: "
                    f"{str(frame.at[index, column])!r} is not a finite number"
                )
            continue
        text = frame[column].astype(str).str.strip()
        values = pd.to_numeric(text, errors="coerce")
        bad = values.isna() | ~np.isfinite(values.fillna(0.0))
        if bad.any():
            index = bad.idxmax()
            raise ConfigError(
                f"{source}: row {int(index) + 1}, column {column}: {frame.at[index, column]!r} is not a finite number"
            )
        out[column] = values.astype(float)
    return out


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


def condition_groups(table: pd.DataFrame):
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
    results = []
    for label, pose, conditions, group in condition_groups(table):
        _check_constant_command(group, [*_COMMAND, *(cmd for cmd, _ in angles)], source)
        _check_single_frame(group, source)
        _check_unique_cycles(group, source)
        group = group.sort_values("cycle", kind="stable")
        axes = measured_axes(group)
        attained = group[list(axes)].to_numpy()
        full_command = group[list(_COMMAND)].to_numpy()[0]
        command = full_command[[_ATTAINED.index(c) for c in axes]]
        try:
            repeatability = pose_repeatability(attained)
        except InsufficientData as exc:
            raise type(exc)(f"{source}: pose {label!r}: {exc}") from None
        ap_u, _ = accuracy_uncertainty(attained, command, instrument_u_mm=instrument_u_mm, k=k)
        u_rp = repeatability_uncertainty(attained, resamples=resamples) if len(attained) >= 3 else 0.0
        orientation = None
        if angles:
            attained_deg = group[[att for _, att in angles]].to_numpy()
            orientation = (
                orientation_accuracy(attained_deg, group[[cmd for cmd, _ in angles]].to_numpy()[0]),
                orientation_repeatability(attained_deg),
            )
        results.append(
            PoseResult(
                label=label,
                pose=pose,
                conditions=conditions,
                commanded_mm=tuple(float(v) for v in full_command),
                accuracy=pose_accuracy(attained, command),
                repeatability=repeatability,
                ap_u=ap_u,
                rp_u=expanded(repeatability.rp_mm, u_rp, unit="mm", k=k),
                orientation_accuracy=orientation[0] if orientation else None,
                orientation_repeatability=orientation[1] if orientation else None,
                angle_names=tuple(att[0] for _, att in angles),
                axis_names=tuple(c[0] for c in axes),
            )
        )
    return results


def pose_result_json(result: PoseResult) -> dict:
    """The JSON object of one pose for ``bench analyze iso9283 --json``."""
    ax, ay, az = (dict(zip(result.axis_names, result.accuracy.ap_axes_mm)).get(a) for a in "xyz")  # None: not measured
    out = {
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
    if result.orientation_accuracy is not None:
        for name, ap, rp in zip(
            result.angle_names, result.orientation_accuracy.ap_deg, result.orientation_repeatability.rp_deg
        ):
            out[f"AP{name}_deg"] = ap
            out[f"RP{name}_deg"] = rp
    if result.conditions:
        out["pose"] = result.pose
        out.update(dict(result.conditions))
    return out


def _paired_by_cycle(table: pd.DataFrame, first_pose: str, second_pose: str):
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


# -- streamed arrivals: position stabilisation time and overshoot (ISO 9283 7.4, 7.5) ---------------------------------


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
            (int(cycle), arrival["t_s"].to_numpy(float), arrival[list(_ATTAINED)].to_numpy(float))
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
