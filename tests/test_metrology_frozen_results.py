"""The pose analysis gives the very figures it gave before its per-pose overhead was cut (issue 34): every AP, RP,
U, coverage factor and orientation figure of `analyze_poses`, `pose_file_results` (whole and a chunk at a time)
and the public uncertainty functions equals, with ``==``, the value the implementation of commit 59874f5 computes
on the same data (kept verbatim in tests/pose_analysis_59874f5.py).

The reference is that code run here, not stored numbers: numpy's power and BLAS's dot differ in the last bit between
CPU families (AVX-512's SVML, FMA kernels), so stored figures would hold on one machine only; the same code on the
same machine gives the same bits, and any change of the arithmetic's order shows.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import tests.pose_analysis_59874f5 as before
from bench.errors import ConfigError, InsufficientData
from bench.metrology.iso9283 import pose_accuracy, pose_repeatability
from bench.metrology.pose_stream import pose_file_results
from bench.metrology.tables import POSE_NUMERIC_COLUMNS, analyze_poses, pose_table, read_table_csv
from bench.metrology.uncertainty import (
    accuracy_uncertainty,
    coverage_factor,
    repeatability_uncertainty,
    repeatability_uncertainty_delta,
    welch_satterthwaite,
)


def _table(
    seed: int,
    cycles: tuple[int, ...],
    *,
    axes: str = "xyz",
    angles: str = "",
    conditions: bool = False,
    frame: bool = False,
    shuffled: bool = False,
    exact_pose: bool = False,
) -> pd.DataFrame:
    """A pose table of ``len(cycles)`` poses (``cycles[i]`` cycles each), anisotropic scatter, the given columns."""
    rng = np.random.default_rng(seed)
    rows: list[dict[str, Any]] = []
    for p, n in enumerate(cycles):
        command = rng.uniform(-200, 200, 3).round(3)
        bias = rng.normal(0, 0.5, 3)
        angle_command = rng.uniform(-180, 180, len(angles)).round(2)
        for velocity in (50.0, 100.0) if conditions else (100.0,):
            for cycle in range(1, n + 1):
                attained = command if exact_pose and p == 0 else command + bias + rng.normal(0, [0.3, 0.2, 0.05])
                row: dict[str, Any] = {"pose": f"P{p + 1}", "cycle": cycle}
                row.update({f"cmd_{a}_mm": command[i] for i, a in enumerate("xyz")})
                row.update({f"{a}_mm": attained[i] for i, a in enumerate("xyz") if a in axes})
                for i, a in enumerate(angles):
                    row[f"cmd_{a}_deg"] = angle_command[i]
                    row[f"{a}_deg"] = (angle_command[i] + rng.normal(0, 0.4) + 180.0) % 360.0 - 180.0
                if conditions:
                    row["velocity_pct"], row["load_kg"] = velocity, 2.0
                if frame:
                    row["frame"] = "base"
                rows.append(row)
    table = pd.DataFrame(rows)
    if shuffled:
        table = table.iloc[rng.permutation(len(table))].reset_index(drop=True)
    return table


#: (name, table, instrument_u_mm, k): every code path of the per-pose analysis (measurement-model U(RP) up to 100
#: cycles, the delta method above, 2 cycles (no U(RP)), AP = 0, angles near ±180°, conditions, partial axes).
CASES = [
    ("model-and-delta", lambda: _table(1, (3, 10, 57, 101, 240)), 0.0, 2.0),
    ("instrument-k3", lambda: _table(2, (2, 12, 150)), 0.05, 3.0),
    ("angles-conditions-frame", lambda: _table(3, (8, 130), angles="abc", conditions=True, frame=True), 0.01, 2.0),
    ("one-angle-shuffled", lambda: _table(4, (6, 7, 300), angles="b", shuffled=True), 0.02, 2.0),
    ("planar-camera", lambda: _table(5, (5, 140), axes="xy", angles="c"), 0.0, 2.0),
    ("one-axis", lambda: _table(6, (4, 110), axes="z"), 0.1, 2.0),
    ("exact-pose", lambda: _table(7, (10, 200), exact_pose=True), 0.0, 2.0),
    ("exact-pose-instrument", lambda: _table(8, (10, 200), exact_pose=True), 0.03, 2.0),
]


def _leaves(value: Any, path: str = "") -> list[tuple[str, Any]]:
    """Every number (and label) of a result with its path, for a message that names the one that differs."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return [leaf for f in dataclasses.fields(value) for leaf in _leaves(getattr(value, f.name), f"{path}.{f.name}")]
    if isinstance(value, (list, tuple)):
        return [leaf for i, v in enumerate(value) for leaf in _leaves(v, f"{path}[{i}]")]
    return [(path, value)]


def _assert_identical(now: Any, before_: Any) -> None:
    """``now`` and ``before_`` hold the same fields, each equal with ``==`` (NaN matching NaN) and of the same type."""
    a, b = _leaves(now), _leaves(before_)
    assert [p for p, _ in a] == [p for p, _ in b]
    differing = [
        (p, x, y) for (p, x), (_, y) in zip(a, b) if not (x == y or (x != x and y != y)) or type(x) is not type(y)
    ]
    assert not differing, differing[:5]


@pytest.mark.parametrize("name, make, instrument_u_mm, k", CASES, ids=[c[0] for c in CASES])
def test_every_figure_of_every_pose_is_the_one_it_was(tmp_path: Path, name, make, instrument_u_mm, k):
    frame = make()
    table = pose_table(frame, partial_axes=True)
    reference = before.analyze_poses(pose_table(frame, partial_axes=True), instrument_u_mm=instrument_u_mm, k=k)
    _assert_identical(analyze_poses(table, instrument_u_mm=instrument_u_mm, k=k), reference)
    # through a file: read whole, and a chunk at a time (pose_stream groups the rows itself)
    path = tmp_path / f"{name}.csv"
    frame.to_csv(path, index=False, float_format="%.6f")
    read = pose_table(read_table_csv(path, numeric=POSE_NUMERIC_COLUMNS), partial_axes=True)
    reference = before.analyze_poses(read, instrument_u_mm=instrument_u_mm, k=k)
    for chunk_rows in (None, 97):
        results = pose_file_results(path, instrument_u_mm=instrument_u_mm, k=k, chunk_rows=chunk_rows)
        _assert_identical(results, reference)


def test_the_cases_exercise_every_path():
    """The cases reach what they are meant to: model and delta U(RP), no U(RP), AP = 0, angles, a plane."""
    poses = [r for _, make, u, k in CASES for r in before.analyze_poses(pose_table(make(), partial_axes=True), k=k)]
    counts = {r.accuracy.n for r in poses}
    assert {2, 3}.issubset(counts) and min(c for c in counts if c > 100) > 100
    assert any(r.accuracy.ap_mm == 0.0 for r in poses)
    assert any(r.rp_u.expanded_uncertainty == 0.0 for r in poses)
    assert any(r.orientation_accuracy for r in poses) and any(r.axis_names == ("x", "y") for r in poses)
    assert len({r.ap_u.coverage_factor for r in poses}) > 5


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(2, 160),
    d=st.integers(1, 3),
    instrument_u_mm=st.sampled_from([0.0, 0.001, 0.05, 2.0]),
    k=st.sampled_from([1.0, 2.0, 3.0]),
    layout=st.sampled_from(["C", "F"]),
)
def test_the_public_functions_give_the_figures_they_gave(seed, n, d, instrument_u_mm, k, layout):
    """Called from outside (any memory layout: a row-major array sums its axes in another order), each public
    function gives the bits it gave, and still checks its inputs."""
    rng = np.random.default_rng(seed)
    points = np.asarray(rng.normal(rng.uniform(-300, 300, d), rng.uniform(0.001, 1.0, d), (n, d)), order=layout)
    command = rng.uniform(-300, 300, d)
    _assert_identical(
        accuracy_uncertainty(points, command, instrument_u_mm=instrument_u_mm, k=k),
        before.accuracy_uncertainty(points, command, instrument_u_mm=instrument_u_mm, k=k),
    )
    _assert_identical(pose_accuracy(points, command), before.pose_accuracy(points, command))
    _assert_identical(pose_repeatability(points), before.pose_repeatability(points))
    if n >= 3:
        assert repeatability_uncertainty(points) == before.repeatability_uncertainty(points)
        assert repeatability_uncertainty_delta(points) == before.repeatability_uncertainty_delta(points)
    contributions, dof = rng.uniform(0, 1, d), [*rng.integers(1, 50, d - 1), math.inf]
    assert welch_satterthwaite(contributions, dof) == before.welch_satterthwaite(contributions, dof)
    nu = float(rng.uniform(1, 200))
    assert coverage_factor(k, nu) == before.coverage_factor(k, nu) == coverage_factor(k, nu)  # cached: the same


def test_the_public_functions_still_check_their_inputs():
    with pytest.raises(ConfigError, match=r"attained_mm: row 1 = \[nan, 0.0, 0.0\], expected finite numbers"):
        accuracy_uncertainty([[0.0, 0.0, 0.0], [np.nan, 0.0, 0.0]], [0.0, 0.0, 0.0])
    with pytest.raises(InsufficientData, match="pose repeatability cycles: 1 sample"):
        pose_repeatability([[0.0, 0.0, 0.0]])
    with pytest.raises(ConfigError, match=r"commanded_mm: shape \(2,\), expected \(3,\)"):
        pose_accuracy([[0.0, 0.0, 0.0]], [0.0, 0.0])
    with pytest.raises(InsufficientData, match="cycles: 2 sample"):
        repeatability_uncertainty_delta([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
