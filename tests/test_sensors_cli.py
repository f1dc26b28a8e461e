"""``bench sensors`` commands end to end through ``bench.cli.main``."""

import io
import json

import pytest

from bench.cli import main


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_mouse_sim_then_read_a_half_circle(tmp_path, capsys):
    path = tmp_path / "mouse.bin"
    code, out, _ = run(
        capsys, "sensors", "mouse-sim", str(path), "--duration-s", "1", "--radius-mm", "10", "--period-s", "2", "--json"
    )
    assert code == 0 and json.loads(out)["events"] > 1000
    code, out, _ = run(capsys, "sensors", "mouse-read", str(path), "--json")
    result = json.loads(out)
    assert code == 0 and result["frames"] == 1000 and result["valid"]
    assert result["count_x"] == -630 and result["x_mm"] == pytest.approx(-20.0, abs=0.0318)  # 800 CPI: 1 count


def test_mouse_read_with_a_calibration_file_and_bad_input(tmp_path, capsys):
    path = tmp_path / "mouse.bin"
    run(capsys, "sensors", "mouse-sim", str(path), "--duration-s", "1", "--radius-mm", "10", "--period-s", "2")
    cal = tmp_path / "cal.json"
    cal.write_text(
        json.dumps(
            {"calibration_id": "xy-1", "date": "2026-11-23", "matrix_mm_per_count": [[0.032, 0.0], [0.0, 0.0315]]}
        )
    )
    code, out, _ = run(capsys, "sensors", "mouse-read", str(path), "--calibration", str(cal), "--json")
    assert json.loads(out)["x_mm"] == pytest.approx(-630 * 0.032) and json.loads(out)["calibration_id"] == "xy-1"
    cal.write_text("{}")
    code, _, err = run(capsys, "sensors", "mouse-read", str(path), "--calibration", str(cal))
    assert code == 2 and "missing keys ['calibration_id', 'date', 'matrix_mm_per_count']" in err
    code, _, err = run(capsys, "sensors", "mouse-read", str(tmp_path / "event99"))
    assert code == 1 and "event99 does not exist; is the mouse plugged in?" in err


def test_grid_decode_figure_10a(capsys):
    code, out, _ = run(
        capsys,
        "sensors",
        "grid-decode",
        "--horizontal",
        "121",
        "--vertical",
        "39",
        "--prior-mm",
        "0",
        "-5",
        "-150",
        "--json",
    )
    result = json.loads(out)
    assert code == 0 and (result["x_mm"], result["y_mm"], result["z_mm"]) == (0.0, -5.0, -150.0)
    assert result["horizontal_lasers"] == ["G5-a"] and result["vertical_status"] == "ok"


def test_tilt_with_bias(capsys):
    code, out, _ = run(
        capsys, "sensors", "tilt", "--h1-mm", "0", "--h2-mm", "0", "--spacing-mm", "40", "--bias-deg", "-4", "--json"
    )
    result = json.loads(out)
    assert code == 0 and result["tilt_corrected_deg"] == 4.0 and result["u_deg"] == pytest.approx(0.024, abs=0.0005)


def test_calliper_entry_appends_and_flushes_each_row(tmp_path, capsys, monkeypatch):
    out_csv = tmp_path / "entries.csv"
    monkeypatch.setattr("sys.stdin", io.StringIO("12.3\nabc\n12,31\n"))
    code, _, err = run(
        capsys,
        "sensors",
        "calliper-entry",
        "--out",
        str(out_csv),
        "--count",
        "2",
        "--expected-mm",
        "12",
        "--label",
        "leg 1",
    )
    rows = out_csv.read_text().splitlines()
    assert code == 0 and rows[0].startswith("t_monotonic_s,t_wall_s,source,value_mm,raw")
    assert [r.split(",")[3] for r in rows[1:]] == ["12.3", "12.31"] and "is not a length" in err
    monkeypatch.setattr("sys.stdin", io.StringIO("13\n"))
    code, _, err = run(capsys, "sensors", "calliper-entry", "--out", str(out_csv), "--count", "2")
    assert code == 2 and "input ended" in err and len(out_csv.read_text().splitlines()) == 4


def test_mouse_list_runs_without_input_devices(capsys):
    code, out, _ = run(capsys, "sensors", "mouse-list", "--json")
    assert code == 0 and isinstance(json.loads(out)["mice"], list)


def test_every_sensor_describes_itself_for_the_run_manifest(tmp_path):
    import numpy as np

    from bench.sensors.calibration import CountsCalibration
    from bench.sensors.camera_spot import LaserSpotCamera, PlaneCalibration
    from bench.sensors.lasergrid import LaserGridSensor
    from bench.sensors.mouse import EvdevMouse
    from bench.simulators.camera import SpotCameraSimulator
    from bench.simulators.lasergrid import LaserGridSimulator

    path = tmp_path / "m.bin"
    path.write_bytes(b"")
    cal = CountsCalibration.from_cpi(800)
    sensors = [
        EvdevMouse(str(path), cal, label="XY"),
        LaserGridSensor(LaserGridSimulator().frame_source(lambda: np.zeros(3)), lambda: np.zeros(3)),
        LaserSpotCamera(
            SpotCameraSimulator(np.eye(3)).frame_source(lambda: np.zeros(2)),
            PlaneCalibration(np.eye(3), 0.0, "cam-1", "2026-11-23"),
        ),
    ]
    for sensor in sensors:
        settings = sensor.settings()
        assert json.loads(json.dumps(settings)) == settings and settings["sensor"]
    assert sensors[0].settings()["calibration_hash"] == cal.content_hash()
    sensors[0].close()
