"""Kinematic compensation end to end on the simulated pkm5 with a seeded true geometry: a calibration run of the
D-optimal poses (examples/kinematic_calibration.toml), ``bench calibrate``, then the held-out validation poses
(examples/kinematic_validation.toml) with the calibration in force and with ``--no-kinematic-calibration`` (the
runs of tests/calibrated_pkm5.py, which the report of tests/test_reports_calibration.py reads too)."""

import subprocess
import sys

import numpy as np
import pytest
from calibrated_pkm5 import EXAMPLES, SEED, calibrated_runs

from bench.calibration.compensate import NEWEST, OFF, select_calibration
from bench.cli import main
from bench.errors import ConfigError
from bench.rigs.mice import LIVENESS_ROBOT_ERROR_MM
from bench.rigs.registration import PKM5_RATED_RP_MM
from bench.store import Store
from motion import pkm5
from motion.pkm5.calibration import compensation_geometry, geometry_from_calibration


def _bench(*args, store):
    command = [sys.executable, "-m", "bench.cli", *args, "--store", str(store)]
    return subprocess.run(command, capture_output=True, text=True, timeout=300)


def _ap_mm(store, run_id):
    """Mean over the poses of ISO 9283 AP_P: |mean attained position - commanded position| (iso9283.md §7.2.1)."""
    with Store(store, read_only=True) as s:
        samples = s.samples(run_id, "pose")
    by_pose = {}
    for sample in samples:
        error = [sample.values[k] - sample.values[f"cmd_{k}"] for k in ("x_mm", "y_mm", "z_mm")]
        by_pose.setdefault(sample.pose, []).append(error)
    return float(np.mean([np.linalg.norm(np.mean(errors, axis=0)) for errors in by_pose.values()]))


def test_compensation_cuts_the_pose_error_on_held_out_poses(tmp_path_factory):
    runs = calibrated_runs(tmp_path_factory)
    assert (
        "kinematic calibration: none (no pkm5_kinematics calibration for a robot without a serial "
        "(simulated) in" in runs.said["calibration_run"]
    )
    calibration = runs.calibration
    assert calibration["fit"] == "map" and len(calibration["parameters"]) == 36  # every parameter, the prior
    assert calibration["prior"]["sigma"] == {"leg_offset": 0.3, "scale": 0.005, "joint": 0.3}

    assert (
        f"kinematic calibration in force: pkm5_kinematics v1 (id {calibration['id']} from run "
        f"{runs.calibration_run}; the newest for this robot)"
    ) in runs.said["compensated"]
    assert "kinematic calibration: none (--no-kinematic-calibration)" in runs.said["nominal"]

    with Store(runs.store, read_only=True) as s:
        on, off = s.run(runs.compensated), s.run(runs.nominal)
    assert calibration["id"] in on.calibration_ids and calibration["id"] not in off.calibration_ids
    assert on.settings["kinematic_calibration"]["id"] == calibration["id"]
    assert off.settings["kinematic_calibration"] == {"id": None, "reason": "--no-kinematic-calibration"}
    # the mice's liveness check grants the calibrated robot its own small error, the uncalibrated one 25 mm
    assert on.settings["instrument"]["liveness_robot_error_mm"] == pytest.approx(
        2 * (5 * calibration["ap_after_mm"] + PKM5_RATED_RP_MM), abs=1e-3
    )
    assert off.settings["instrument"]["liveness_robot_error_mm"] == LIVENESS_ROBOT_ERROR_MM
    ap_on, ap_off = _ap_mm(runs.store, runs.compensated), _ap_mm(runs.store, runs.nominal)
    assert ap_off > 0.5  # the true geometry's error, uncompensated (0.98 mm measured)
    assert ap_off / ap_on > 5  # 15.6x measured with this seed


def test_the_registration_moves_the_frame_of_the_calibrated_geometry():
    """Every base joint moved by the registration r: the IK of p + r in the compensation geometry equals the IK of
    p in the identified one (leg lengths depend only on the joints' relative positions)."""
    params = {
        "parameters": {
            "leg_offset_2_mm": {"value": 0.3},
            "pd_5_x_mm": {"value": -0.2},
            "reg_x_mm": {"value": 1.5},
            "reg_y_mm": {"value": -0.7},
            "reg_z_mm": {"value": 2.0},
        }
    }
    poses = np.array([[120.0, 5.0, 310.0, 0.0, 0.1], [130.0, -10.0, 300.0, 0.0, 0.0]])
    shift = np.array([1.5, -0.7, 2.0, 0.0, 0.0])
    identified = pkm5.inverse_kinematics(poses, geometry_from_calibration(params)).lengths_mm
    compensating = pkm5.inverse_kinematics(poses + shift, compensation_geometry(params)).lengths_mm
    assert compensating == pytest.approx(identified, abs=1e-9)
    assert compensation_geometry(params).oa_56_mm == pytest.approx((151.5, -0.7, 62.0))


def test_the_calibration_in_force_is_chosen_per_robot(tmp_path):
    params = {"parameters": {"reg_x_mm": {"value": 0.0}}}
    with Store(tmp_path / "bench.db") as store:
        first = store.add_calibration("pkm5_kinematics", params)
        other = store.add_calibration("pkm5_kinematics", {**params, "dut_serial": "PKM-7"})
        mouse = store.add_calibration("mouse", {"mm_per_count": 0.03})
        simulated = store.add_calibration("pkm5_kinematics", {**params, "simulated": True})
        assert select_calibration(store, "pkm5", NEWEST)[0].id == first.id
        assert select_calibration(store, "pkm5", NEWEST, "PKM-7")[0].id == other.id
        assert select_calibration(store, "pkm5", NEWEST, "PKM-9") == (
            None,
            f"no pkm5_kinematics calibration for robot PKM-9 in {store.path}",
        )
        assert select_calibration(store, "pkm5", OFF) == (None, "--no-kinematic-calibration")
        assert select_calibration(store, "delta4", NEWEST) == (
            None,
            f"no delta4_kinematics calibration for a robot without a serial in {store.path}",
        )
        assert select_calibration(store, "prus3", NEWEST) == (None, "no kinematic calibration exists for the prus3")
        with pytest.raises(
            ConfigError,
            match=f"^--kinematic-calibration {mouse.id}: calibration mouse v1, expected a pkm5_kinematics calibration$",
        ):
            select_calibration(store, "pkm5", mouse.id)
        with pytest.raises(
            ConfigError,
            match=f"^--kinematic-calibration {other.id}: made for robot PKM-7, "
            r"expected one for robot \(no serial\)$",
        ):
            select_calibration(store, "pkm5", other.id)
        # a simulated robot's geometry never reaches hardware, nor the reverse
        assert select_calibration(store, "pkm5", NEWEST, simulated=True)[0].id == simulated.id
        assert select_calibration(store, "pkm5", NEWEST)[0].id == first.id
        with pytest.raises(
            ConfigError,
            match=f"^--kinematic-calibration {simulated.id}: made on a simulated robot, "
            "expected one for hardware robot$",
        ):
            select_calibration(store, "pkm5", simulated.id)


def test_an_unknown_calibration_id_is_one_line(tmp_path):
    done = _bench(
        "run",
        str(EXAMPLES / "kinematic_validation.toml"),
        "--sim",
        "--kinematic-calibration",
        "99",
        "--no-progress",
        store=tmp_path / "bench.db",
    )
    assert done.returncode == 2
    assert done.stderr == f"bench: error: calibration id 99: not found in {tmp_path / 'bench.db'}\n"


def test_a_resume_keeps_the_calibration_of_its_run(tmp_path):
    """A resumed run commands by the calibration that was in force when it started, not a newer one; a run stored
    without one stays without one."""
    from types import SimpleNamespace

    from bench.calibration.compensate import put_in_force
    from bench.launch import RigRequest, _kinematic_calibration
    from bench.rigs.interfaces import Rig
    from bench.rigs.movers import Pkm5Mover

    def rig(stored):
        chosen = _kinematic_calibration(RigRequest(), store, "pkm5", stored, None, "assembled", False)
        mover = Pkm5Mover(SimpleNamespace(geometry=pkm5.DEFAULT_GEOMETRY, fixture="assembled"))
        return put_in_force(Rig(mover, None, None), *chosen)

    params = {"parameters": {"leg_offset_1_mm": {"value": 0.25}, "reg_z_mm": {"value": 1.0}}}
    with Store(tmp_path / "bench.db") as store:
        first = store.add_calibration("pkm5_kinematics", params)
        store.add_calibration("pkm5_kinematics", params)
        resumed = rig({"kinematic_calibration": {"id": first.id}})
        assert resumed.calibration_ids == (first.id,) and resumed.kinematic_calibration.version == 1
        assert resumed.robot.geometry.leg_length_offset_mm[0] == pytest.approx(184.25)
        assert resumed.robot.geometry.oa_12_mm == pytest.approx((-75.0, -129.9, 1.0))
        older = rig({"simulator": {"seed": 0}})
        assert older.calibration_ids == () and older.robot.geometry == pkm5.DEFAULT_GEOMETRY
        assert older.kinematic_calibration.settings() == {"id": None, "reason": "the run was made without one"}
        assert rig({}).kinematic_calibration.version == 2
        with pytest.raises(ConfigError, match="^--kinematic-calibration 1: the actuator-bench commands no poses"):
            _kinematic_calibration(
                RigRequest(kinematic_calibration=1), store, "pkm5", {}, None, "actuator-bench", False
            )


def test_iterative_correction_brings_the_error_within_the_instrument_uncertainty(tmp_path, capsys):
    """Uncompensated robot of a true geometry: ~1 mm off at the first move; the command corrected by the mice's
    reading brings every target within their 0.05 mm standard uncertainty in at most 3 moves."""
    protocol = tmp_path / "correct.toml"
    protocol.write_text(
        'protocol = "iterative_correction"\nrobot = "pkm5"\ntolerance_mm = 0.05\niterations = 3\n'
        "settle_s = 0.2\n[poses]\nT1 = [120, 10, 315]\nT2 = [150, -30, 300]\nT3 = [105, 40, 325]\n"
    )
    store = tmp_path / "bench.db"
    assert (
        main(
            [
                "run",
                str(protocol),
                "--sim",
                "--true-geometry-seed",
                str(SEED),
                "--ideal",
                "--no-progress",
                "--store",
                str(store),
            ]
        )
        == 0
    )
    with Store(store, read_only=True) as s:
        samples = s.samples(int(capsys.readouterr().out.split()[-1]), "pose")
    errors = {}
    for sample in samples:  # iteration = cycle; the target is the first iteration's command
        target = next(t for t in samples if t.pose == sample.pose and t.cycle == 1)
        errors.setdefault(sample.pose, []).append(
            max(abs(sample.values[k] - target.values[f"cmd_{k}"]) for k in ("x_mm", "y_mm", "z_mm"))
        )
    assert set(errors) == {"T1", "T2", "T3"}
    assert max(e[0] for e in errors.values()) > 0.5  # 0.70-1.01 mm measured at the first move
    for pose, series in errors.items():
        assert len(series) <= 3 and series[-1] <= 0.05, (pose, series)
        assert all(e > 0.05 for e in series[:-1]), (pose, series)  # stops at the first move within tolerance


def test_a_correction_moves_only_the_measured_axes():
    """A laser-grid reading with the vertical screen undecoded has no z: z keeps its command."""
    from bench.protocols.iterative import corrected_command

    command, errors = corrected_command(
        (10.0, 5.0, -200.0), (10.2, 5.0, -200.0), {"x_mm": 10.6, "y_mm": 4.9, "horizontal_valid": 1.0}
    )
    assert command == pytest.approx((9.6, 5.1, -200.0)) and errors == pytest.approx({"x_mm": 0.4, "y_mm": -0.1})
