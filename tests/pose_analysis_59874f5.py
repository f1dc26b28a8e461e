"""The pose analysis as commit 59874f5 computed it (before issue 34 cut its per-pose overhead), kept verbatim but for
the docstrings: the reference that tests/test_metrology_frozen_results.py compares today's figures with, bit for bit.

Functions unchanged since (grouping checks, orientation figures, the measurement model's cached factors, input
checks) are imported from bench; everything whose code the change touched is copied here. Not for use elsewhere.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from bench.errors import ConfigError, InsufficientData
from bench.metrology._validation import as_points, as_vector, require_count
from bench.metrology.iso9283 import PoseAccuracy, PoseRepeatability, orientation_accuracy, orientation_repeatability
from bench.metrology.tables import (
    _ATTAINED,
    _COMMAND,
    ANGLE_PAIRS,
    CONDITION_COLUMNS,
    PoseGroup,
    PoseResult,
    _check_constant_command,
    _check_single_frame,
    _check_unique_cycles,
    condition_groups,
    measured_axes,
)
from bench.metrology.uncertainty import _BOOTSTRAP_CHUNK_CYCLES, Measured
from bench.metrology.uncertainty_model import (
    MODEL_MAX_CYCLES,
    _rp_of_samples,
    _rp_relative_half_width,
    _scatter_shape,
)


def _checked_pose_groups(
    table: pd.DataFrame, commands: Sequence[str], source: str
) -> Iterator[tuple[str, str, tuple[tuple[str, float], ...], np.ndarray]]:
    keys = [c for c in CONDITION_COLUMNS if c in table.columns and table[c].nunique() > 1]
    if keys:
        codes = table.groupby([table["pose"].astype(str), *(table[c] for c in keys)], sort=False).ngroup().to_numpy()
    else:
        codes = pd.factorize(table["pose"].astype(str))[0]
    codes = codes.astype(np.int16 if codes.max(initial=0) < 2**15 else np.int64)
    order = np.argsort(codes, kind="stable")
    grouped, cycles = (codes[order], table["cycle"].to_numpy(float)[order])
    same_group = grouped[1:] == grouped[:-1]
    if not np.all(cycles[1:][same_group] > cycles[:-1][same_group]):
        order = np.lexsort((table["cycle"].to_numpy(float), codes))
        cycles = table["cycle"].to_numpy(float)[order]
    starts = np.flatnonzero(np.r_[True, grouped[1:] != grouped[:-1]])
    first_rows = order[starts]
    checked = [table[c].to_numpy(float) for c in commands]
    if "frame" in table.columns:
        checked.append(pd.factorize(table["frame"].astype(str).str.strip())[0])
    if np.any(cycles[1:][same_group] == cycles[:-1][same_group]) or any(
        np.any(values != values[first_rows][codes]) for values in checked
    ):
        for _, _, _, group in condition_groups(table):
            _check_constant_command(group, commands, source)
            _check_single_frame(group, source)
            _check_unique_cycles(group, source)
    poses, key_values = (table["pose"], [table[c].to_numpy() for c in keys])
    for rows in np.split(order, starts[1:]):
        pose, conditions = (str(poses.iat[rows[0]]), tuple(((c, float(v[rows[0]])) for c, v in zip(keys, key_values))))
        label = pose if not conditions else f"{pose} ({', '.join((f'{n}={v:g}' for n, v in conditions))})"
        yield (label, pose, conditions, rows)


def analyze_poses(
    table: pd.DataFrame, *, instrument_u_mm: float = 0.0, k: float = 2.0, resamples: int = 1000
) -> list[PoseResult]:
    source = table.attrs.get("source", "table")
    angles = [(cmd, att) for cmd, att in ANGLE_PAIRS if cmd in table.columns]
    axes = measured_axes(table)
    columns = {c: table[c].to_numpy(float) for c in (*axes, *_COMMAND, *(c for pair in angles for c in pair))}
    results = []
    for label, pose, conditions, rows in _checked_pose_groups(table, [*_COMMAND, *(c for c, _ in angles)], source):
        attained = np.array([columns[c][rows] for c in axes]).T
        attained_deg = np.array([columns[att][rows] for _, att in angles]).T if angles else None
        commands = {c: float(columns[c][rows[0]]) for c in (*_COMMAND, *(cmd for cmd, _ in angles))}
        group = PoseGroup(label, pose, conditions, axes, attained, angles, attained_deg, commands)
        results.append(pose_result(group, source=source, instrument_u_mm=instrument_u_mm, k=k, resamples=resamples))
    return results


def pose_result(group: PoseGroup, *, source: str, instrument_u_mm: float, k: float, resamples: int) -> PoseResult:
    full_command = np.array([group.commands[c] for c in _COMMAND])
    command = full_command[[_ATTAINED.index(c) for c in group.axes]]
    attained = group.attained
    try:
        repeatability = pose_repeatability(attained)
    except InsufficientData as exc:
        raise type(exc)(f"{source}: pose {group.label!r}: {exc}") from None
    ap_u, _ = accuracy_uncertainty(attained, command, instrument_u_mm=instrument_u_mm, k=k)
    u_rp = repeatability_uncertainty(attained, resamples=resamples) if len(attained) >= 3 else 0.0
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
        accuracy=pose_accuracy(attained, command),
        repeatability=repeatability,
        ap_u=ap_u,
        rp_u=expanded(repeatability.rp_mm, u_rp, unit="mm", k=k),
        orientation_accuracy=orientation[0] if orientation else None,
        orientation_repeatability=orientation[1] if orientation else None,
        angle_names=tuple((att[0] for _, att in group.angles)),
        axis_names=tuple(c[0] for c in group.axes),
    )


def pose_accuracy(attained_mm: ArrayLike, commanded_mm: ArrayLike) -> PoseAccuracy:
    attained = as_points("attained_mm", attained_mm)
    command = as_vector("commanded_mm", commanded_mm, length=attained.shape[1])
    require_count("pose accuracy cycles", len(attained), 1)
    barycentre = attained.mean(axis=0)
    deviation = barycentre - command
    return PoseAccuracy(
        ap_mm=float(np.sqrt(np.sum(deviation**2))),
        ap_axes_mm=tuple(float(v) for v in deviation),
        barycentre_mm=tuple(float(v) for v in barycentre),
        n=len(attained),
    )


def pose_repeatability(attained_mm: ArrayLike) -> PoseRepeatability:
    attained = as_points("attained_mm", attained_mm)
    require_count("pose repeatability cycles", len(attained), 2)
    distances = np.sqrt(np.sum((attained - attained.mean(axis=0)) ** 2, axis=1))
    l_mean = float(distances.mean())
    s_l = float(distances.std(ddof=1))
    return PoseRepeatability(
        rp_mm=l_mean + 3.0 * s_l,
        l_mean_mm=l_mean,
        s_l_mm=s_l,
        spread_3s_axes_mm=tuple(float(v) for v in 3.0 * attained.std(axis=0, ddof=1)),
        n=len(attained),
    )


def expanded(value: float, standard_uncertainty: float, *, unit: str, k: float = 2.0) -> Measured:
    if standard_uncertainty < 0 or not np.isfinite(standard_uncertainty):
        raise ConfigError(f"standard_uncertainty = {standard_uncertainty}, expected a finite number >= 0")
    return Measured(float(value), float(k * standard_uncertainty), float(k), unit)


def welch_satterthwaite(contributions: ArrayLike, degrees_of_freedom: ArrayLike) -> float:
    u = np.asarray(contributions, dtype=float)
    nu = np.asarray(degrees_of_freedom, dtype=float)
    if u.shape != nu.shape:
        raise ConfigError(f"contributions {u.shape} and degrees_of_freedom {nu.shape}, expected the same shape")
    denominator = np.sum(u**4 / nu)
    return float("inf") if denominator == 0 else float(np.sum(u**2) ** 2 / denominator)


def accuracy_uncertainty(
    attained_mm: ArrayLike, commanded_mm: ArrayLike, *, instrument_u_mm: float = 0.0, k: float = 2.0
) -> tuple[Measured, tuple[Measured, ...]]:
    attained = as_points("attained_mm", attained_mm)
    n = len(attained)
    require_count("accuracy uncertainty cycles", n, 2)
    deviation = attained.mean(axis=0) - np.asarray(commanded_mm, dtype=float)
    type_a = attained.var(axis=0, ddof=1) / n
    u_axes = np.sqrt(type_a + instrument_u_mm**2)
    norm = float(np.linalg.norm(deviation))
    weights = np.zeros_like(deviation) if norm == 0 else (deviation / norm) ** 2
    if norm == 0:
        weights[np.argmax(u_axes)] = 1.0
    u_norm = float(np.sqrt(np.sum(weights * u_axes**2)))
    axes = tuple(
        (
            expanded(
                d,
                u,
                unit="mm",
                k=coverage_factor(k, welch_satterthwaite([math.sqrt(a), instrument_u_mm], [n - 1, math.inf])),
            )
            for d, u, a in zip(deviation, u_axes, type_a)
        )
    )
    nu_norm = welch_satterthwaite([*np.sqrt(weights * type_a), instrument_u_mm], [*[n - 1] * len(type_a), math.inf])
    return (expanded(norm, u_norm, unit="mm", k=coverage_factor(k, nu_norm)), axes)


def coverage_factor(k: float, degrees_of_freedom: float) -> float:
    if not math.isfinite(degrees_of_freedom):
        return float(k)
    from scipy.special import stdtrit

    level = math.erf(k / math.sqrt(2.0))
    return float(stdtrit(degrees_of_freedom, (1.0 + level) / 2.0))


def repeatability_uncertainty(
    attained_mm: ArrayLike, *, resamples: int = 1000, seed: int = 0, method: str = "auto"
) -> float:
    points = as_points("attained_mm", attained_mm)
    require_count("bootstrap cycles", len(points), 3)
    if method not in ("auto", "bootstrap", "delta", "model"):
        raise ConfigError(f"method = {method!r}, expected 'auto', 'bootstrap', 'delta' or 'model'")
    if method == "model" or (method == "auto" and len(points) <= MODEL_MAX_CYCLES):
        return repeatability_uncertainty_model(points)
    if method == "delta" or method == "auto":
        return repeatability_uncertainty_delta(points)
    n = len(points)
    rng = np.random.default_rng(seed)
    chunk = max(1, _BOOTSTRAP_CHUNK_CYCLES // n)
    rp = np.empty(resamples)
    for first in range(0, resamples, chunk):
        count = min(chunk, resamples - first)
        samples = points[rng.integers(0, n, size=(count, n))]
        distances = np.sqrt(np.sum((samples - samples.mean(axis=1, keepdims=True)) ** 2, axis=2))
        rp[first : first + count] = distances.mean(axis=1) + 3.0 * distances.std(axis=1, ddof=1)
    return float(rp.std(ddof=1))


def repeatability_uncertainty_delta(attained_mm: ArrayLike) -> float:
    points = as_points("attained_mm", attained_mm)
    n = len(points)
    require_count("cycles", n, 3)
    offsets = points - points.mean(axis=0)
    distances = np.sqrt(np.einsum("ij,ij->i", offsets, offsets))
    mean_l = distances.mean()
    spread = distances.std(ddof=1)
    if spread == 0.0:
        return 0.0
    with np.errstate(invalid="ignore", divide="ignore"):
        units = np.where(distances[:, None] > 0, offsets / distances[:, None], 0.0)
    deviation = distances - mean_l
    mean_u = units.mean(axis=0)
    mean_w = (deviation[:, None] * units).mean(axis=0)
    influence = (
        deviation - offsets @ mean_u + 3.0 / (2.0 * spread) * (deviation**2 - spread**2 - 2.0 * (offsets @ mean_w))
    )
    return float(np.sqrt(np.sum(influence**2)) / n)


def repeatability_uncertainty_model(attained_mm: ArrayLike, *, k: float = 2.0) -> float:
    points = as_points("attained_mm", attained_mm, dims=None)
    n = len(points)
    require_count("cycles", n, 3)
    rp = float(_rp_of_samples(points))
    if rp == 0.0:
        return 0.0
    level = math.erf(k / math.sqrt(2.0))
    return rp * _rp_relative_half_width(n, _scatter_shape(points), level) / k
