"""CLI tests of ``bench kin ... delta4|prus3``: JSON keys and values, one-line errors and exit codes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bench.cli import main


def run_json(capsys, argv):
    code = main(argv)
    captured = capsys.readouterr()
    return code, json.loads(captured.out), captured.err


def test_delta4_ik_json_keys_and_golden_values(capsys):
    code, result, err = run_json(capsys, ["kin", "ik", "delta4", "-70", "60", "-200", "--json", "--geometry", "thesis"])
    assert code == 0 and err == ""
    assert set(result) == {"servo_deg", "coord_deg", "knees_mm", "reachable", "reason"}
    np.testing.assert_allclose(result["servo_deg"], [129.3, 126.6058, 73.7283, 78.5895], atol=1e-4)  # TV1
    np.testing.assert_allclose(result["coord_deg"], [275.7, 261.6058, 208.7283, 326.4105], atol=1e-4)
    assert np.shape(result["knees_mm"]) == (4, 3)
    assert result["reachable"] is True and result["reason"] is None


def test_delta4_unreachable_pose_exits_2_with_one_line(capsys):
    code = main(["kin", "ik", "delta4", "70", "0", "-100", "--json"])
    captured = capsys.readouterr()
    assert code == 2
    assert json.loads(captured.out)["reason"] == "servo_limit (leg 1)"
    assert captured.err == "bench: error: point (70, 0, -100) mm is not reachable: servo_limit (leg 1)\n"


def test_delta4_fk_json_keys_and_least_squares_vector(capsys):
    code, result, _ = run_json(
        capsys, ["kin", "fk", "delta4", "129.25", "126.5", "73.7", "78.375", "--json", "--geometry", "thesis"]
    )
    assert code == 0 and set(result) == {"pose", "residual_mm"}
    assert set(result["pose"]) == {"x_mm", "y_mm", "z_mm"}
    np.testing.assert_allclose(
        [result["pose"][k] for k in ("x_mm", "y_mm", "z_mm")], [-69.881, 60.158, -199.776], atol=2e-3
    )
    assert result["residual_mm"] == pytest.approx(0.072, abs=1e-3)


def test_delta4_fk_closed_form_and_text_output(capsys):
    assert (
        main(
            [
                "kin",
                "fk",
                "delta4",
                "90.75",
                "90.75",
                "90.75",
                "90.75",
                "--method",
                "closed_form",
                "--geometry",
                "thesis",
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "z_mm = -199.4821" in out  # TV3: -19.9482 cm


def test_delta4_fk_failure_is_one_line_exit_1(capsys):
    code = main(["kin", "fk", "delta4", "45", "135", "45", "135", "--method", "closed_form"])
    err = capsys.readouterr().err
    assert code == 1 and err.count("\n") == 1 and "no_solution" in err


def test_delta4_workspace_json(capsys):
    code, result, _ = run_json(capsys, ["kin", "workspace", "delta4", "--samples", "2000", "--z-mm", "-200", "--json"])
    assert code == 0 and result["samples"] == 2000 and result["squares"][0]["z_mm"] == -200
    assert result["volume_mm3"] > 0 and result["squares"][0]["half_width_mm"] == 92.5


def test_prus3_ik_json_and_unreachable(capsys):
    code, result, _ = run_json(capsys, ["kin", "ik", "prus3", "450", "150", "-600", "3", "-4", "5", "--json"])
    assert code == 0 and {"sliders_mm", "reachable"} <= set(result)
    np.testing.assert_allclose(result["sliders_mm"], [786.485461661, 1050.695470943, 1001.494762965], atol=1e-6)  # TV-3
    code, result, _ = run_json(
        capsys, ["kin", "ik", "prus3", "450", "150", "-600", "3", "-4", "5", "--branch", "-1", "-1", "-1", "--json"]
    )
    np.testing.assert_allclose(result["sliders_mm"], [278.873026383, 159.768000119, 322.683277930], atol=1e-6)
    code = main(["kin", "ik", "prus3", "300", "0", "-600", "0", "0", "0", "--json"])
    captured = capsys.readouterr()
    assert code == 2 and json.loads(captured.out)["reachable"] is False
    assert (
        captured.err == "bench: error: pose (300, 0, -600, 0, 0, 0) mm/deg is not reachable: revolute_range (leg 1)\n"
    )


def test_prus3_fk_from_leg_joints(capsys):
    argv = [
        "kin",
        "fk",
        "prus3",
        "786.485461661",
        "1050.695470943",
        "1001.494762965",
        "--revolute-deg",
        "-27.718275",
        "-45",
        "-34.628282",
        "--universal-deg",
        "0",
        "24.569670",
        "19.032488",
        "14.652766",
        "0",
        "5.455263",
        "--json",
    ]
    code, result, _ = run_json(capsys, argv)
    assert code == 0 and set(result) == {"pose", "residual_mm"}
    pose = [result["pose"][k] for k in ("x_mm", "y_mm", "z_mm", "alpha_deg", "beta_deg", "gamma_deg")]
    np.testing.assert_allclose(pose, [450, 150, -600, 3, -4, 5], atol=1e-4)


def test_bad_arguments_are_refused_by_argparse(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["kin", "ik", "prus3", "450", "150", "-600", "3", "-4", "5", "--branch", "2", "1", "1"])
    assert exit_info.value.code == 2 and "expected +1 or -1" in capsys.readouterr().err
