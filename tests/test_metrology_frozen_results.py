"""The pose analysis gives the very figures it gave before its per-pose overhead was cut (issue 34): every AP, RP,
U, coverage factor and orientation figure of `analyze_poses`, `pose_file_results` (whole and a chunk at a time)
and the public uncertainty functions equals, with ``==``, the value the implementation of commit 59874f5 computed
on the same seeded tables (stored in ``tests/data/frozen_pose_results.json`` with full ``repr`` precision).

Regenerate the file only on purpose (a change of the figures is a change of the documented method):
``python tests/test_metrology_frozen_results.py --regenerate``.
"""

from __future__ import annotations

import dataclasses
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

from bench.metrology.iso9283 import pose_accuracy, pose_repeatability
from bench.metrology.pose_stream import pose_file_results
from bench.metrology.tables import analyze_poses, pose_table
from bench.metrology.uncertainty import (
    accuracy_uncertainty,
    repeatability_uncertainty,
    repeatability_uncertainty_delta,
)

FROZEN = Path(__file__).parent / "data" / "frozen_pose_results.json"


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


def _plain(value: Any) -> Any:
    """A result as JSON-ready data: floats kept exactly (``repr`` round-trips), tuples as lists."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, dict):
        return {key: _plain(v) for key, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    return value


def _analyses(tmp: Path) -> dict[str, Any]:
    """Every figure of every case, by the current implementation."""
    figures: dict[str, Any] = {}
    for name, make, instrument_u_mm, k in CASES:
        frame = make()
        results = analyze_poses(pose_table(frame, partial_axes=True), instrument_u_mm=instrument_u_mm, k=k)
        figures[f"{name}/analyze_poses"] = _plain(results)
        path = tmp / f"{name}.csv"
        frame.to_csv(path, index=False, float_format="%.6f")
        for chunk_rows in (None, 97):
            results = pose_file_results(path, instrument_u_mm=instrument_u_mm, k=k, chunk_rows=chunk_rows)
            figures[f"{name}/pose_file_results/{chunk_rows}"] = _plain(results)
    rng = np.random.default_rng(9)
    for n in (2, 3, 20, 150):
        points = rng.normal(0, [0.3, 0.2, 0.1], size=(n, 3)) + [1.0, -2.0, 0.5]
        command = [0.9, -2.1, 0.5]
        figures[f"public/{n}"] = _plain(
            {
                "accuracy_uncertainty": accuracy_uncertainty(points, command, instrument_u_mm=0.02),
                "pose_accuracy": pose_accuracy(points, command),
                "pose_repeatability": pose_repeatability(points),
                "repeatability_uncertainty": repeatability_uncertainty(points) if n >= 3 else None,
                "repeatability_uncertainty_delta": repeatability_uncertainty_delta(points) if n >= 3 else None,
            }
        )
    return figures


@pytest.fixture(scope="module")
def analyses(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    # through JSON as the frozen file went (keys sorted; a float's repr round-trips exactly)
    return json.loads(json.dumps(_analyses(tmp_path_factory.mktemp("frozen")), sort_keys=True))


@pytest.fixture(scope="module")
def frozen() -> dict[str, Any]:
    return json.loads(FROZEN.read_text())


def _leaves(value: Any, path: str = "") -> list[tuple[str, Any]]:
    if isinstance(value, dict):
        return [leaf for key, v in value.items() for leaf in _leaves(v, f"{path}.{key}")]
    if isinstance(value, list):
        return [leaf for i, v in enumerate(value) for leaf in _leaves(v, f"{path}[{i}]")]
    return [(path, value)]


@pytest.mark.parametrize(
    "key",
    [
        f"{name}/{what}"
        for name, *_ in CASES
        for what in ("analyze_poses", "pose_file_results/None", "pose_file_results/97")
    ]
    + [f"public/{n}" for n in (2, 3, 20, 150)],
)
def test_every_figure_equals_the_frozen_one_exactly(analyses, frozen, key):
    now, before = _leaves(analyses[key]), _leaves(frozen[key])
    assert [p for p, _ in now] == [p for p, _ in before]
    differing = [(p, a, b) for (p, a), (_, b) in zip(now, before) if not (a == b or (a != a and b != b))]
    assert not differing, differing[:5]


def test_the_frozen_figures_exercise_every_path(frozen):
    """The cases reach what they are meant to: model and delta U(RP), no U(RP), AP = 0, Type B only (k = 2)."""
    poses = [r for key, results in frozen.items() if key.endswith("analyze_poses") for r in results]
    counts = {r["accuracy"]["n"] for r in poses}
    assert {2, 3}.issubset(counts) and max(counts) > 100
    assert any(r["accuracy"]["ap_mm"] == 0.0 for r in poses)
    assert any(r["rp_u"]["expanded_uncertainty"] == 0.0 for r in poses)
    assert any(r["orientation_accuracy"] for r in poses) and any(r["axis_names"] == ["x", "y"] for r in poses)
    assert len({r["ap_u"]["coverage_factor"] for r in poses}) > 5 and all(
        math.isfinite(r["ap_u"]["expanded_uncertainty"]) for r in poses
    )


if __name__ == "__main__" and sys.argv[1:] == ["--regenerate"]:
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        FROZEN.write_text(json.dumps(_analyses(Path(folder)), indent=None, sort_keys=True) + "\n")
    print(f"wrote {FROZEN}")
