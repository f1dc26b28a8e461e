"""``bench kin ... pkm5`` on the command line: JSON contracts and one-line errors."""

import json
import subprocess
import sys

import pytest

from bench.cli import main


def run_json(capsys, argv):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, json.loads(out), err


def test_ik_json(capsys):
    code, data, _ = run_json(capsys, ["kin", "ik", "pkm5", "186.11", "0", "312.8", "--json"])
    assert code == 2  # 244.0005 mm is just past the 244 mm window
    assert set(data) == {"lengths_mm", "tilt_deg", "reachable", "reason"}
    assert data["lengths_mm"] == pytest.approx([244.000527] * 4 + [218.633989] * 2, abs=1e-6)
    assert data["tilt_deg"] == pytest.approx([50.3243] * 4 + [90.0] * 2, abs=1e-4)
    assert data["reachable"] is False and "leg 1 length 244.001 mm" in data["reason"]


def test_ik_reachable_with_alpha(capsys):
    code, data, err = run_json(capsys, ["kin", "ik", "pkm5", "111.31", "-20", "310", "--alpha", "5", "--json"])
    assert code == 0 and err == ""
    assert data["reachable"] is True and data["reason"] is None
    assert data["lengths_mm"][4] != pytest.approx(data["lengths_mm"][5])


def test_unreachable_is_one_line_without_traceback():
    proc = subprocess.run(
        [sys.executable, "-m", "bench.cli", "kin", "ik", "pkm5", "300", "0", "300"], capture_output=True, text=True
    )
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert proc.stderr.startswith("bench: error: pose (300, 0, 300) mm") and "leg 1 length 316.729 mm" in proc.stderr


def test_fk_json(capsys):
    code, data, _ = run_json(capsys, ["kin", "fk", "pkm5", "184", "184", "184", "184", "192", "192", "--json"])
    assert code == 0
    assert set(data) >= {"pose", "converged", "iterations", "residual_mm"}
    assert set(data["pose"]) == {"x_mm", "y_mm", "z_mm", "alpha_deg", "beta_deg"}
    assert data["pose"]["x_mm"] == pytest.approx(87.82, abs=0.005)
    assert data["pose"]["z_mm"] == pytest.approx(295.83, abs=0.005)
    assert data["converged"] is True and data["iterations"] >= 1


def test_fk_beta_pose(capsys):
    # 000 Table A.10 row (133.68, -99.6, 280.91, beta 15.38) via its exact lengths (pkm5.md §6.1)
    lengths = ["189.955978", "201.924662", "234.534580", "247.030085", "194.180705", "194.180705"]
    code, data, _ = run_json(capsys, ["kin", "fk", "pkm5", *lengths, "--json"])
    assert code == 0
    assert data["pose"]["beta_deg"] == pytest.approx(15.38, abs=1e-4)
    assert data["pose"]["alpha_deg"] == 0.0


def test_workspace_json(capsys):
    code, data, _ = run_json(
        capsys, ["kin", "workspace", "pkm5", "--samples", "20000", "--hull-points", "2000", "--seed", "1", "--json"]
    )
    assert code == 0
    assert {"volume_mm3", "stderr_mm3", "hull_volume_mm3"} <= set(data)
    assert 0.78e6 < data["volume_mm3"] < 0.87e6 and data["stderr_mm3"] > 0
    assert data["hull_volume_mm3"] > data["volume_mm3"]


def test_workspace_bad_samples(capsys):
    assert main(["kin", "workspace", "pkm5", "--samples", "0"]) == 2
    assert "--samples = 0" in capsys.readouterr().err


def test_kin_robots_lists_every_model(capsys):
    code, data, _ = run_json(capsys, ["kin", "robots", "--json"])
    assert code == 0
    assert list(data) == ["pkm5", "delta4", "prus3"]
    assert data["pkm5"]["pose_fields"] == ["x_mm", "y_mm", "z_mm", "alpha_deg", "beta_deg"]
    assert data["pkm5"]["joints"][4] == {"name": "L5_mm", "low": 192.0, "high": 252.0}
