"""``bench analyze ...`` through bench.cli.main: JSON shape, readable output, one-line errors and exit codes."""

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench.cli import main

DATA = Path(__file__).resolve().parents[1] / "examples" / "data"
HEADER = "pose,cycle,cmd_x_mm,cmd_y_mm,cmd_z_mm,x_mm,y_mm,z_mm"


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_iso9283_json(capsys):
    code, out, _ = _run(capsys, "analyze", "iso9283", str(DATA / "iso9283_example.csv"), "--json")
    assert code == 0
    poses = json.loads(out)["poses"]
    assert list(poses) == ["P1", "P2", "P3", "P4", "P5"]  # report order, whatever the cycle order
    p1 = poses["P1"]
    for key in ("n", "AP_mm", "APx_mm", "APy_mm", "APz_mm", "RP_mm", "barycentre_mm", "APa_deg", "RPc_deg", "U_AP_mm"):
        assert key in p1
    assert p1["n"] == 10
    assert p1["AP_mm"] == pytest.approx((p1["APx_mm"] ** 2 + p1["APy_mm"] ** 2 + p1["APz_mm"] ** 2) ** 0.5)
    assert [b - c for b, c in zip(p1["barycentre_mm"], p1["commanded_mm"])] == pytest.approx(
        [p1["APx_mm"], p1["APy_mm"], p1["APz_mm"]]
    )


def test_iso9283_table_without_angles_has_no_orientation_keys(capsys, tmp_path):
    path = tmp_path / "s.csv"
    path.write_text("\n".join([HEADER, "P1,1,0,0,0,0.1,0,0", "P1,2,0,0,0,0.3,0,0"]))
    code, out, _ = _run(capsys, "analyze", "iso9283", str(path), "--json")
    p1 = json.loads(out)["poses"]["P1"]
    assert code == 0 and "APa_deg" not in p1
    assert p1["APx_mm"] == pytest.approx(0.2) and p1["RP_mm"] == pytest.approx(0.1)


def test_iso9283_readable_table(capsys):
    code, out, _ = _run(capsys, "analyze", "iso9283", str(DATA / "iso9283_example.csv"))
    assert code == 0
    assert out.splitlines()[0].split()[:4] == ["pose", "n", "AP_mm", "APx_mm"]
    assert "orientation (deg)" in out


def test_every_analysis_says_whether_its_u_includes_the_instrument(capsys):
    # Issue 32 item 2: the default used to be a silent instrument u = 0 and the output said only "U with k = 2".
    example = str(DATA / "iso9283_example.csv")
    code, out, _ = _run(capsys, "analyze", "iso9283", example)
    assert code == 0 and "U excludes the instrument: none declared (--instrument-u-mm)." in out
    code, out, _ = _run(capsys, "analyze", "iso9283", example, "--json")
    assert json.loads(out)["U_budget"] == "U excludes the instrument: none declared (--instrument-u-mm)"
    code, out, _ = _run(capsys, "analyze", "iso9283", example, "--instrument-u-mm", "0.05", "--json")
    declared = json.loads(out)["poses"]["P1"]
    assert json.loads(out)["U_budget"] == "U includes the instrument: u = 0.05 mm per axis (--instrument-u-mm)"
    code, out, _ = _run(capsys, "analyze", "iso9283", example, "--json")
    bare = json.loads(out)["poses"]["P1"]
    assert declared["U_AP_mm"] > bare["U_AP_mm"]
    code, out, _ = _run(capsys, "analyze", "distance", example)
    assert code == 0 and "U excludes the instrument: none declared" in out


@pytest.mark.parametrize(
    "text, message",
    [
        ("pose,cycle,x_mm\nP1,1,0\n", "missing column(s) cmd_x_mm"),
        (f"{HEADER}\nP1,1,0,0,0,0,0,0\nP1,2,0,0,0,zero,0,0\n", "row 2, column x_mm: 'zero' is not a finite number"),
        (f"{HEADER}\nP1,1,0,0,0,0,0,nan\n", "row 1, column z_mm: 'nan' is not a finite number"),
        ("", "not a readable CSV table"),
        (f"{HEADER}\nP1,1,0,0,0,0,0,0,9\n", "row 1: 9 fields, expected 8 as in the header"),
    ],
)
def test_bad_csv_gives_one_line_and_exit_2(capsys, tmp_path, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    code, out, err = _run(capsys, "analyze", "iso9283", str(path), "--json")
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and "Traceback" not in err
    assert message in err and err.startswith("bench: error: ")


def test_too_few_cycles_exits_nonzero_naming_the_pose(capsys, tmp_path):
    path = tmp_path / "one.csv"
    path.write_text(f"{HEADER}\nP3,1,0,0,0,0,0,0\n")
    code, _, err = _run(capsys, "analyze", "iso9283", str(path))
    assert code == 1
    assert "pose 'P3'" in err and "at least 2 required" in err and err.count("\n") == 1


def test_distance_command(capsys):
    code, out, _ = _run(capsys, "analyze", "distance", str(DATA / "iso9283_example.csv"), "--json")
    result = json.loads(out)
    assert code == 0 and result["n"] == 10
    assert result["commanded_distance_mm"] == pytest.approx(0.8 * 100 * 3**0.5)  # P2-P4 = 0.8 L √3
    assert result["RD_mm"] >= 0


def test_drift_command(capsys):
    code, out, _ = _run(capsys, "analyze", "drift", str(DATA / "iso9283_example.csv"), "--window-s", "100", "--json")
    result = json.loads(out)
    assert code == 0 and [w["n"] for w in result["windows"]] == [5, 5]
    assert result["dAP_mm"] == pytest.approx(abs(result["windows"][0]["AP_mm"] - result["windows"][1]["AP_mm"]))


def test_actuator_command_reproduces_table_8_1(capsys):
    code, out, _ = _run(capsys, "analyze", "actuator", str(DATA / "actuator_tables_a1_a6.csv"), "--json")
    actuators = json.loads(out)["actuators"]
    assert code == 0
    assert [round(a["repeatability_mm"], 2) for a in actuators.values()] == [0.18, 0.12, 0.13, 0.14, 0.12, 0.19]
    assert actuators["5"]["mean_deviation_mm"][3] == pytest.approx(-0.158, abs=0.0005)


def test_payload_command_reproduces_table_8_5(capsys):
    code, out, _ = _run(capsys, "analyze", "payload", str(DATA / "payload_table_a14.csv"), "--json")
    legs = json.loads(out)["legs"]
    assert code == 0
    assert [legs[str(i)]["max_error_mm"] for i in range(1, 7)] == [0.21, 0.29, 0.27, 0.28, 0.2, 0.18]
    assert [legs[str(i)]["load_at_max_kg"] for i in range(1, 7)] == [7.08, 7.08, 7.08, 12.07, 8.44, 5.27]


def test_actuator_without_control_resolution(capsys, tmp_path):
    path = tmp_path / "a.csv"
    path.write_text("actuator,cmd_mm,travel_mm\n1,10,10.01\n1,10,9.99\n")
    code, _, err = _run(capsys, "analyze", "actuator", str(path))
    assert code == 2 and "no cr_mm column and no --cr-mm given" in err
    assert _run(capsys, "analyze", "actuator", str(path), "--cr-mm", "0.01")[0] == 0


def test_mouse_command_table_a28(capsys):
    code, out, _ = _run(capsys, "analyze", "mouse", str(DATA / "mouse_table_a28.csv"), "--json")
    five = json.loads(out)["distances"]["5"]
    assert code == 0 and five["n"] == 18
    assert five["mean_delta_counts"] == pytest.approx(24.33, abs=0.005)
    assert five["three_sigma_counts"] == pytest.approx(1.78, abs=0.005)  # Table A.25, speed 4, Y, 5 mm


def test_mouse_command_matrix_fit(capsys):
    code, out, _ = _run(capsys, "analyze", "mouse", str(DATA / "mouse_matrix_example.csv"), "--json")
    result = json.loads(out)
    true_a = [[0.031738, -0.000407], [0.000611, 0.032045]]  # inverse of the generating B = [[31.5, 0.4], [-0.6, 31.2]]
    assert code == 0 and result["method"] == "matrix" and result["n"] == 60
    assert np.array(result["A_mm_per_count"]) == pytest.approx(np.array(true_a), abs=5e-5)


def test_mouse_command_unknown_layout(capsys, tmp_path):
    path = tmp_path / "m.csv"
    path.write_text("x,y\n1,2\n")
    code, _, err = _run(capsys, "analyze", "mouse", str(path))
    assert code == 2 and "expected columns distance_mm, position" in err


cells = st.sampled_from(["0", "1.5", "-2", "1e3", "", "abc", "nan", "inf", "P1", "P2", " 3 ", "1,5"])


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.lists(cells, min_size=8, max_size=8), min_size=0, max_size=6))
def test_any_table_gives_a_result_or_one_line_error(capsys, tmp_path, rows):
    path = tmp_path / "fuzz.csv"
    path.write_text("\n".join([HEADER, *(",".join(r) for r in rows)]) + "\n")
    code, out, err = _run(capsys, "analyze", "iso9283", str(path), "--json")
    assert code in (0, 1, 2)
    if code == 0:
        assert "poses" in json.loads(out)
    else:
        assert err.startswith("bench: error: ") and err.count("\n") == 1


def test_payload_command_shows_each_legs_worst_error_with_its_sign(capsys, tmp_path):
    """A leg whose signed maximum is +0.002 mm at 0.45 kg but whose error reaches -0.248 mm at 25.23 kg: the
    worst is -0.248 mm at 25.23 kg (the signed maximum hid it)."""
    path = tmp_path / "legs.csv"
    path.write_text(
        "load_kg,leg,error_mm\n0.45,1,0.002\n12.07,1,-0.1\n25.23,1,-0.248\n0.45,2,0.01\n12.07,2,0.05\n25.23,2,0.03\n"
    )
    code, out, _ = _run(capsys, "analyze", "payload", str(path), "--json")
    legs = json.loads(out)["legs"]
    assert code == 0
    assert (legs["1"]["worst_error_mm"], legs["1"]["load_at_worst_kg"]) == (-0.248, 25.23)
    assert (legs["2"]["worst_error_mm"], legs["2"]["load_at_worst_kg"]) == (0.05, 12.07)
    _, text, _ = _run(capsys, "analyze", "payload", str(path))
    assert "-0.248   25.23" in text.splitlines()[1]
