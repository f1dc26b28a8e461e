"""AP/RP of an instrument that measures a subset of the position axes (the camera: x, y on its plane): the ISO 9283
formulas restricted to the measured axes (bench.metrology.tables.analyze_poses), against numpy; a table without any
attained axis is refused in one line."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from bench.errors import ConfigError
from bench.metrology.tables import analyze_poses, pose_result_json, pose_table


def _table(rng, columns=("x_mm", "y_mm")) -> pd.DataFrame:
    rows = []
    for pose, command in (("P1", (10.0, -5.0, -150.0)), ("P2", (-20.0, 8.0, -180.0))):
        for cycle in range(1, 8):
            attained = np.array(command) + [0.3, -0.2, 0.9] + rng.normal(0.0, 0.05, 3)
            row = {"pose": pose, "cycle": cycle, **{f"cmd_{a}_mm": c for a, c in zip("xyz", command)}}
            row |= {c: attained["xyz".index(c[0])] for c in columns}
            rows.append(row)
    frame = pd.DataFrame(rows)
    frame.attrs["source"] = "camera.csv"
    return frame


def test_planar_ap_and_rp_are_the_iso_formulas_over_x_and_y():
    frame = _table(np.random.default_rng(4))
    results = analyze_poses(pose_table(frame, partial_axes=True))
    for result in results:
        rows = frame[frame["pose"] == result.pose]
        points = rows[["x_mm", "y_mm"]].to_numpy()
        command = rows[["cmd_x_mm", "cmd_y_mm"]].to_numpy()[0]
        barycentre = points.mean(axis=0)
        distances = np.linalg.norm(points - barycentre, axis=1)
        assert result.axis_names == ("x", "y") and len(result.commanded_mm) == 3
        assert result.accuracy.ap_axes_mm == pytest.approx(barycentre - command, abs=1e-12)
        assert result.accuracy.ap_mm == pytest.approx(np.linalg.norm(barycentre - command), abs=1e-12)
        assert result.repeatability.rp_mm == pytest.approx(distances.mean() + 3 * distances.std(ddof=1), abs=1e-12)
        entry = pose_result_json(result)
        assert entry["APz_mm"] is None and entry["measured_axes"] == ["x", "y"]
    # the z offset of 0.9 mm is not in the figures: the 3-D AP of the same readings is larger
    full = analyze_poses(pose_table(_table(np.random.default_rng(4), ("x_mm", "y_mm", "z_mm"))))
    assert all(f.accuracy.ap_mm > r.accuracy.ap_mm + 0.5 for f, r in zip(full, results))
    assert "measured_axes" not in pose_result_json(full[0]) and full[0].axis_names == ("x", "y", "z")


def test_without_partial_axes_or_without_any_axis_the_table_is_refused():
    frame = _table(np.random.default_rng(1))
    with pytest.raises(ConfigError, match=r"^camera.csv: missing column\(s\) z_mm"):
        pose_table(frame)
    with pytest.raises(
        ConfigError,
        match=r"^camera.csv: missing column\(s\) x_mm, y_mm, z_mm; found .*, expected at "
        r"least one measured position axis$",
    ):
        pose_table(frame.drop(columns=["x_mm", "y_mm"]), partial_axes=True)
