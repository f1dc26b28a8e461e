"""The sensor registry (bench.sensor_kinds): every sensor-specific table of bench reads it, so a new sensor is its own
files plus one registration. The toy laser tracker of tests/toy_sensor.py is added through register() alone and then
is a station table, a capability, an instrument the builder opens, a device `bench station check` checks, a stand-in
a rehearsal starts and a source of stored columns with their units."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
import toy_sensor

from bench.cli import main
from bench.columns import Column
from bench.errors import ConfigError
from bench.reports.content import collect as collect_pose_report
from bench.rigs.station import parse_station
from bench.sensor_kinds import SENSOR_KINDS, SensorKind, capability_sources, register, sensor_kind, sensor_names
from bench.store import SampleMismatch, Store, validate_sample

ROOT = Path(__file__).resolve().parents[1]

TOY = SensorKind(
    name="toy_tracker",
    title="a toy laser tracker (tests/toy_sensor.py)",
    spec="toy_sensor:parse",
    provides=("pose",),
    devices=("log",),
    instrument="toy_sensor:open_tracker",
    check="toy_sensor:check",
    stand_in="toy_sensor:stand_in",
    columns=(
        Column("tracker_seq", "1", "int", "toy tracker: the reading's number in its log", False),
        Column("tracker_range_mm", "mm", "float", "toy tracker: distance from its base to the target", False),
    ),
)

TOY_STATION = """[station]
name = "toy-bench"
[robot]
kind = "pkm5"
[controller]
port = "/dev/ttyACM9"
[toy_tracker]
log = "/dev/tracker0"
base_mm = [100, 0, 0]
"""


@pytest.fixture()
def toy():
    register(TOY)
    yield TOY
    del SENSOR_KINDS["toy_tracker"]


def test_the_shipped_sensors_are_registered_in_the_order_stations_prefer_their_instruments():
    assert sensor_names()[:4] == ("mice", "camera", "laser_grid", "calliper")
    assert sensor_kind("mice").robots == ("pkm5",) and sensor_kind("laser_grid").robots == ("delta4",)
    # the message a station without a pose instrument gets, written once by the registry
    assert capability_sources("pose") == "[mice] (pkm5), [camera], or [laser_grid] (delta4)"
    assert capability_sources("mouse_counts") == "[mice]"
    with pytest.raises(ConfigError, match="sensor 'tracker': expected one of mice, camera, laser_grid, calliper"):
        sensor_kind("tracker")


def test_a_name_registered_twice_with_another_record_is_refused(toy):
    with pytest.raises(ValueError, match="'toy_tracker' is registered already"):
        register(dataclasses.replace(toy, provides=("pose", "arrival")))


def test_the_store_declares_the_columns_a_sensor_registers_and_only_those():
    values = {"cmd_x_mm": 1.0, "cmd_y_mm": 2.0, "cmd_z_mm": 3.0, "x_mm": 1.0, "tracker_range_mm": 5.0}
    with pytest.raises(SampleMismatch, match="column 'tracker_range_mm' is not declared"):
        validate_sample("pose", values)
    register(TOY)
    try:
        validate_sample("pose", values)
        with pytest.raises(SampleMismatch, match=r"tracker_seq = 2.5, expected an integer"):
            validate_sample("pose", {**values, "tracker_seq": 2.5})
        with pytest.raises(SampleMismatch, match="column 'tracker_range_mm' is not declared"):
            validate_sample("arrival", values)  # the toy declared its columns for pose samples only
    finally:
        del SENSOR_KINDS["toy_tracker"]


@pytest.mark.parametrize(
    ("name", "unit"), [("tracker_range_mm", "deg"), ("tracker_range", "mm"), ("tracker_seq", "counts"), ("t_s", "1")]
)
def test_a_column_whose_name_does_not_end_in_its_unit_is_refused(name, unit):
    with pytest.raises(ValueError, match=f"column '{name}' in '{unit}': a column's name ends in its unit"):
        Column(name, unit, "float", "a toy tracker's column")


def test_a_toy_sensor_is_a_station_table_with_its_capabilities_and_devices(toy, tmp_path):
    import tomllib

    data = tomllib.loads(TOY_STATION)
    station = parse_station(data, source="toy.toml")
    assert station.sensor("toy_tracker").base_mm == (100.0, 0.0, 0.0)
    assert station.capabilities() == {"assembled", "pose"}
    assert station.devices == {"controller.port": "/dev/ttyACM9", "toy_tracker.log": "/dev/tracker0"}
    assert station.settings()["toy_tracker"] == {"log": "/dev/tracker0", "base_mm": (100.0, 0.0, 0.0)}
    bad = {**data, "toy_tracker": {"log": "/dev/tracker0", "base_mm": [1, 2]}}
    with pytest.raises(ConfigError, match=r"^toy.toml: toy_tracker.base_mm = \[1, 2\], expected the tracker's base"):
        parse_station(bad, source="toy.toml")
    shared = {**data, "toy_tracker": {"log": "/dev/ttyACM9"}}
    with pytest.raises(ConfigError, match="toy_tracker.log = '/dev/ttyACM9', expected a device of its own"):
        parse_station(shared, source="toy.toml")


def test_without_its_registration_the_toy_table_is_unknown():
    import tomllib

    with pytest.raises(ConfigError, match=r"unknown table \[toy_tracker\], expected one of \[station\]"):
        parse_station(tomllib.loads(TOY_STATION), source="toy.toml")


def test_station_check_checks_a_toy_sensor_by_its_own_check(toy, tmp_path, capsys):
    station = tmp_path / "toy.toml"
    station.write_text(TOY_STATION)
    assert main(["station", "check", str(station), "--sim", "--json"]) == 0
    checks = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [c["key"] for c in checks] == ["controller.port", "toy_tracker.log"]
    assert checks[1]["ok"] and checks[1]["detail"] == "0 readings"  # the simulator's truth log, before any move


def test_a_rehearsed_protocol_captures_with_a_toy_sensor_and_stores_its_declared_columns(toy, tmp_path, capsys):
    station, store_path = tmp_path / "toy.toml", tmp_path / "toy.db"
    station.write_text(TOY_STATION)
    protocol = ROOT / "examples" / "iso9283_pose_quick.toml"
    run = ["run", str(protocol), "--station", str(station), "--sim", "--ideal", "--speed-factor", "20000"]
    assert main([*run, "--store", str(store_path), "--no-progress"]) == 0, capsys.readouterr().err
    with Store(store_path) as store:
        (record,) = store.runs()
        samples = [s for s in store.samples(record.id) if s.kind == "pose"]
    assert len(samples) == 15  # 5 poses x 3 cycles
    assert record.settings["instrument"]["instrument"] == "toy laser tracker"
    assert record.settings["station"]["toy_tracker"]["base_mm"] == [100.0, 0.0, 0.0]
    for sample in samples:
        values = sample.values
        assert {"x_mm", "y_mm", "z_mm", "tracker_seq", "tracker_range_mm"} <= set(values)
        measured = np.array([values["x_mm"], values["y_mm"], values["z_mm"]])
        commanded = np.array([values["cmd_x_mm"], values["cmd_y_mm"], values["cmd_z_mm"]])
        # the ideal simulated robot attains its command to its steps' quantisation (far below 0.05 mm)
        np.testing.assert_allclose(measured, commanded, atol=0.05)
        assert values["tracker_range_mm"] == pytest.approx(math.dist(measured, (100.0, 0.0, 0.0)))
    assert [s.values["tracker_seq"] for s in samples] == sorted({s.values["tracker_seq"] for s in samples})
    # the export states each column's unit and meaning as the toy's record declared them
    out = tmp_path / "toy.csv"
    assert main(["export", str(record.id), "--store", str(store_path), "--out", str(out)]) == 0
    columns = json.loads(Path(f"{out}.meta.json").read_text())["columns"]
    assert columns["tracker_range_mm"]["unit"] == "mm"
    assert columns["tracker_range_mm"]["meaning"] == "toy tracker: distance from its base to the target"
    assert columns["tracker_seq"]["unit"] == "1"
    # the report's uncertainty budget takes the instrument's u from the settings it stated
    with Store(store_path) as store:
        report = collect_pose_report(store, record.id, resamples=20)
    assert report.instrument.sigma_mm == toy_sensor.U_MM
    assert [row.done for row in report.deviations if row.topic == "sensor"][0].startswith(
        "toy laser tracker; u = 0.005"
    )
