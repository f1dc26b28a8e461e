"""The typed rig: what it records beside its devices' settings, in the stored format the reports and resumes read
(bench.rigs.interfaces.Rig.settings)."""

from __future__ import annotations

from runner_support import StandInMover

from bench.rigs.interfaces import KinematicCalibration, Rig, SimulatorRecord
from bench.rigs.station import load_station


class _Robot(StandInMover):
    def settings(self):
        return {"driver": "stand-in"}


class _Instrument:
    def settings(self):
        return {"instrument": "stand-in"}


def test_a_bare_rig_records_its_devices_and_time_base_only():
    rig = Rig(_Robot(), _Instrument(), None, speed_factor=50.0)
    assert rig.settings() == {
        "robot": {"driver": "stand-in"},
        "instrument": {"instrument": "stand-in"},
        "speed_factor": 50.0,
        "time_base": "simulated s (wall x speed factor 50)",
    }


def test_a_station_rig_records_the_station_the_device_under_test_and_what_is_in_force():
    station = load_station("examples/stations/delta4_camera.toml")
    rig = Rig(
        _Robot(),
        _Instrument(),
        None,
        station=station,
        registration={"utc": "2026-12-04T15:00:00+00:00"},  # filed by the runner per segment, not here
        kinematic_calibration=KinematicCalibration("newest for DELTA4-0001", 7, "delta4_kinematics", 2, 41),
        simulator=SimulatorRecord(3, station="examples/stations/delta4_camera.toml", truth_log="/tmp/truth.jsonl"),
    )
    settings = rig.settings()
    assert settings["station"]["source"].endswith("delta4_camera.toml") and settings["station"]["robot"] == "delta4"
    assert settings["dut"] == {"dut_serial": "DELTA4-0001", "laboratory": "Parallel robots lab"}
    assert settings["kinematic_calibration"] == {
        "id": 7,
        "name": "delta4_kinematics",
        "version": 2,
        "source_run_id": 41,
        "reason": "newest for DELTA4-0001",
    }
    assert settings["simulator"] == {
        "seed": 3,
        "station": "examples/stations/delta4_camera.toml",
        "truth_log": "/tmp/truth.jsonl",
    }
    assert "registration" not in settings and "registrations" not in settings


def test_none_in_force_and_a_bare_simulator_are_recorded_as_before():
    rig = Rig(
        _Robot(),
        _Instrument(),
        None,
        kinematic_calibration=KinematicCalibration("the run was made without one"),
        simulator=SimulatorRecord(4, ideal=True, true_geometry_seed=9),
    )
    settings = rig.settings()
    assert settings["kinematic_calibration"] == {"id": None, "reason": "the run was made without one"}
    assert settings["simulator"] == {"seed": 4, "ideal": True, "true_geometry_seed": 9}
    assert Rig(_Robot(), _Instrument(), None, simulator=SimulatorRecord(4)).settings()["simulator"] == {"seed": 4}
