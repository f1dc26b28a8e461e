"""A delta4 kinematic calibration in force (docs/calibration.md): the driver's IK of every command and the plan's
pre-flight (reach, joint limits) use the calibrated geometry, the run records which calibration was in force, and
``--no-kinematic-calibration`` turns it off. Independent paths: the calibrated legs' IK of
:mod:`motion.delta4.calibration` (``commanded_servo_deg``) and the bytes of the servo mapping."""

from __future__ import annotations

import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

from bench.calibration.compensate import calibrated_geometry
from bench.protocols.kinematics import robot_model
from bench.rigs.movers import DeltaMover
from bench.robots import delta4_wire as wire
from bench.robots.delta4 import Delta4Controller
from bench.robots.testing import ScriptedPort
from bench.store import Store
from motion import delta4
from motion.delta4.calibration import attained_positions, commanded_servo_deg, compensation_geometry

PARAMS = {
    "parameters": {
        "servo_zero_1_deg": {"value": 0.4},
        "upper_arm_2_mm": {"value": -0.3},
        "sideways_3_mm": {"value": 0.25},
        "reg_x_mm": {"value": 0.5},
        "reg_y_mm": {"value": -0.3},
    }
}
TARGET = (-70.0, -70.0, -180.0)
PROTOCOL = 'protocol = "delta_positioning"\nrobot = "delta4"\ncycles = 2\nsettle_s = 0.1\n'


def _message(servo_deg) -> str:
    values = wire.LegacyVbMapping().to_bytes(np.asarray(servo_deg))
    return "".join(wire.format_servo_command(i, int(v)).decode() for i, v in enumerate(values))


def test_the_calibrated_ik_puts_the_calibrated_robot_on_the_target_in_the_instrument_frame():
    geometry = compensation_geometry(PARAMS)
    points = np.array([TARGET, (0.0, 0.0, -200.0), (50.0, -50.0, -160.0)])
    servo = delta4.inverse_kinematics(points, geometry).servo_deg
    names = [n for n in PARAMS["parameters"] if not n.startswith("reg_")]
    values = [PARAMS["parameters"][n]["value"] for n in names]
    # the identified robot stands where the reading (attained + registration) is the target
    assert attained_positions(servo, names, values) + [0.5, -0.3, 0.0] == pytest.approx(points, abs=1e-9)
    assert servo == pytest.approx(
        commanded_servo_deg(points, list(PARAMS["parameters"]), [e["value"] for e in PARAMS["parameters"].values()]),
        abs=1e-9,
    )
    assert np.abs(servo - delta4.inverse_kinematics(points).servo_deg).max() > 0.3


def test_the_mover_commands_by_the_geometry_in_force():
    record = type("Record", (), {"id": 7, "name": "delta4_kinematics", "version": 1, "params": PARAMS})()
    geometry = calibrated_geometry(record)
    calibrated = _message(delta4.inverse_kinematics([TARGET], geometry).servo_deg[0])
    documented = _message(delta4.inverse_kinematics([TARGET]).servo_deg[0])
    assert calibrated != documented
    mover = DeltaMover(Delta4Controller(ScriptedPort([(calibrated, "z"), ("z", "")]), settle_timeout_s=0.5))
    assert mover.geometry is None
    mover.use_geometry(geometry)
    mover.move_to(TARGET, velocity_pct=100.0)  # the port refuses any other bytes
    assert mover.geometry is geometry


def test_the_mover_sends_fine_references_by_the_geometry_in_force_once_the_controller_offers_them():
    record = type("Record", (), {"id": 7, "name": "delta4_kinematics", "version": 1, "params": PARAMS})()
    geometry = calibrated_geometry(record)
    angles = delta4.inverse_kinematics([TARGET], geometry).servo_deg[0]
    fine = "".join(wire.format_fine_command(i, int(round(a * 100))).decode() for i, a in enumerate(angles))
    mover = DeltaMover(Delta4Controller(ScriptedPort([("C", "c01125X"), (fine, "z"), ("z", "")]), settle_timeout_s=0.5))
    mover.controller.probe_fine_references()
    mover.use_geometry(geometry)
    mover.move_to(TARGET, velocity_pct=100.0)  # the port refuses any other bytes
    assert mover.settings()["fine_reference"]["in_use"] is True


def test_the_preflight_checks_reach_and_limits_by_the_calibrated_geometry():
    geometry = compensation_geometry({"parameters": {"servo_zero_1_deg": {"value": -50.0}}})
    targets = np.array([TARGET, (0.0, 0.0, -200.0)])
    model = robot_model("delta4")
    assert model.check(targets).reachable.tolist() == [True, True]
    check = replace(model, geometry=geometry).check(targets)
    assert check.reachable.tolist() == [False, True] and check.reason[0] == "servo_limit (leg 1)"


def _bench(*args, store, cwd):
    command = [sys.executable, "-m", "bench.cli", *args, "--store", str(store)]
    return subprocess.run(command, capture_output=True, text=True, timeout=300, cwd=cwd)


def test_a_run_records_the_calibration_in_force_and_can_turn_it_off(tmp_path):
    protocol = tmp_path / "positioning.toml"
    protocol.write_text(PROTOCOL)
    store = tmp_path / "bench.db"
    with Store(store) as s:
        record = s.add_calibration("delta4_kinematics", {**PARAMS, "simulated": True}, notes="test")
    done = _bench("run", str(protocol), "--sim", "--no-progress", store=store, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert (
        f"kinematic calibration in force: delta4_kinematics v1 (id {record.id}; the newest for this robot)"
        in done.stderr
    )
    on = int(done.stdout.split()[-1])
    done = _bench(
        "run", str(protocol), "--sim", "--no-progress", "--no-kinematic-calibration", store=store, cwd=tmp_path
    )
    assert done.returncode == 0, done.stderr
    assert "kinematic calibration: none (--no-kinematic-calibration)" in done.stderr
    off = int(done.stdout.split()[-1])
    with Store(store) as s:
        run_on, run_off = s.run(on), s.run(off)
    assert record.id in run_on.calibration_ids and record.id not in run_off.calibration_ids
    assert run_on.settings["kinematic_calibration"]["id"] == record.id
    # the simulated controller answered the probe: the run sent fine references, and says so
    assert run_on.settings["robot"]["fine_reference"]["in_use"] is True
    assert run_off.settings["kinematic_calibration"] == {"id": None, "reason": "--no-kinematic-calibration"}


def test_a_target_the_calibrated_geometry_cannot_reach_is_refused_before_anything_moves(tmp_path):
    protocol = tmp_path / "positioning.toml"
    protocol.write_text(PROTOCOL)
    store = tmp_path / "bench.db"
    with Store(store) as s:
        s.add_calibration(
            "delta4_kinematics", {"parameters": {"servo_zero_1_deg": {"value": -50.0}}, "simulated": True}
        )
    done = _bench("run", str(protocol), "--sim", "--no-progress", store=store, cwd=tmp_path)
    assert done.returncode == 2 and done.stderr.count("\n") == 2, done.stderr
    assert "target P2 (x -70.00 mm, y -70.00 mm, z -180.00 mm) is not reachable: servo_limit (leg 1)" in done.stderr
    assert (
        _bench(
            "run", str(protocol), "--sim", "--no-progress", "--no-kinematic-calibration", store=store, cwd=tmp_path
        ).returncode
        == 0
    )


def test_a_calibration_of_another_robot_is_refused_in_one_line(tmp_path):
    from bench.calibration.compensate import NEWEST, select_calibration
    from bench.errors import ConfigError

    with Store(tmp_path / "bench.db") as store:
        pkm5_record = store.add_calibration("pkm5_kinematics", {"parameters": {}})
        delta4_record = store.add_calibration("delta4_kinematics", PARAMS)
        assert select_calibration(store, "delta4", NEWEST)[0].id == delta4_record.id
        assert select_calibration(store, "pkm5", NEWEST)[0].id == pkm5_record.id
        with pytest.raises(
            ConfigError,
            match=f"^--kinematic-calibration {pkm5_record.id}: calibration "
            "pkm5_kinematics v1, expected a delta4_kinematics calibration$",
        ):
            select_calibration(store, "delta4", pkm5_record.id)
        with pytest.raises(
            ConfigError,
            match=f"^--kinematic-calibration {delta4_record.id}: no kinematic "
            "calibration exists for the prus3, expected none$",
        ):
            select_calibration(store, "prus3", delta4_record.id)
