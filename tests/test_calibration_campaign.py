"""A calibration campaign on a robot with play (bench.metrology.kinematic_campaign) and the multi-start search
(bench.metrology.kinematic_search), through ``bench calibrate`` on stored runs of the calibration protocol's 30
poses (examples/kinematic_calibration.toml) attained by seeded true geometries."""

import json
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from bench.cli import main
from bench.metrology.kinematic_campaign import erratic_poses, plan_campaign, pose_means
from bench.robots.pkm5_kinematics import steps_for_pose
from bench.simulators.true_geometry import attained_poses, true_deviations, true_geometry
from bench.store import Store
from motion.pkm5.calibration import PARAMETERS, REGISTRATION, ForwardModel, modes_of_poses, tolerance

ALL = REGISTRATION + PARAMETERS
PROTOCOL = Path(__file__).resolve().parent.parent / "examples" / "kinematic_calibration.toml"
REGISTRATION_MM = np.array([3.0, -2.0, 1.0])
MICE_MM = 0.05


@pytest.fixture(scope="module")
def protocol():
    poses = np.array(list(tomllib.loads(PROTOCOL.read_text())["poses"].values()), dtype=float)
    return poses, np.array([steps_for_pose(p) for p in poses]), modes_of_poses(poses)


def _store_campaign(path, poses, readings):
    """A run of ``readings`` (C, N, 3): C cycles of the N poses, in the protocol's order."""
    with Store(path) as store:
        run_id = store.start_run(protocol_name="kinematic_calibration", protocol_version="1", robot="pkm5", config={})
        index = 0
        for cycle, cycle_readings in enumerate(readings, start=1):
            for i, (cmd, meas) in enumerate(zip(poses, cycle_readings)):
                values = {
                    **dict(zip(("cmd_x_mm", "cmd_y_mm", "cmd_z_mm", "cmd_a_deg", "cmd_b_deg"), map(float, cmd))),
                    **dict(zip(("x_mm", "y_mm", "z_mm"), map(float, meas))),
                }
                store.add_sample(
                    run_id, index, values=values, kind="pose", pose=f"C{i + 1:02d}", cycle=cycle, t_s=60.0 * index
                )
                index += 1
    return run_id


def _readings(protocol, seed, cycles, play_mm):
    poses, steps, modes = protocol
    attained = attained_poses(steps, modes, true_geometry(seed))[:, :3] + REGISTRATION_MM
    rng = np.random.default_rng([seed, 8])
    return attained[None] + rng.normal(0.0, 1.0, (cycles, *attained.shape)) * np.hypot(MICE_MM, play_mm)


def _z(stored, seed):
    truth = {**true_deviations(seed), **dict(zip(REGISTRATION, REGISTRATION_MM))}
    return {n: abs(p["value"] - truth[n]) / p["uncertainty"] for n, p in stored["parameters"].items()}


def test_pose_means_weigh_by_the_pooled_scatter_of_the_mean_with_the_instrument_as_floor():
    readings = np.array([[0.0, 1.0], [2.0, 1.0], [10.0, 5.0], [11.0, 5.0], [12.0, 5.0]])
    means = pose_means(readings, [0, 0, 1, 1, 1], instrument_mm=0.5)
    assert means.mean_mm.tolist() == [[1.0, 1.0], [11.0, 5.0]]
    # pooled over the poses: x (1 + 1 + 1 + 0 + 1) / (5 - 2) = 4/3; y: no scatter, so the instrument's 0.5.
    # Each pose's own sum of squares (x: 2 and 2) joins the pooled variance counted as 10 degrees of freedom:
    # pose 0 (2 + 10 * 4/3) / (1 + 10), pose 1 (2 + 10 * 4/3) / (2 + 10)
    assert means.scatter_mm == pytest.approx([np.sqrt(4 / 3), 0.0]) and means.scatter_dof == 3
    own = 2 + 10 * 4 / 3
    assert means.uncertainty_mm == pytest.approx(
        np.array(
            [[np.sqrt(own / 11) / np.sqrt(2), 0.5 / np.sqrt(2)], [np.sqrt(own / 12) / np.sqrt(3), 0.5 / np.sqrt(3)]]
        )
    )
    single = pose_means(readings[:2], [0, 1], instrument_mm=0.5)  # one reading a pose: nothing measured
    assert np.isnan(single.scatter_mm).all() and single.uncertainty_mm.tolist() == [[0.5, 0.5], [0.5, 0.5]]


def test_a_pose_that_scatters_far_beyond_the_others_is_erratic():
    rng = np.random.default_rng(4)
    readings = rng.normal(0.0, 0.6, (10, 30, 3))  # 10 cycles of 30 poses
    readings[:, 0, 0] = rng.normal(0.0, 7.0, 10)  # pose 0 spreads in x as the simulated fold pose did
    index = np.tile(np.arange(30), 10)
    erratic = erratic_poses(readings.reshape(-1, 3), index)
    assert erratic.tolist() == [True] + [False] * 29
    # its own variance ratio against the other poses' pooled one, by hand: above the F quantile at 1e-6
    from scipy.stats import f

    own = np.var(readings[:, 0, 0], ddof=1)
    rest = np.sum((readings[:, 1:, 0] - readings[:, 1:, 0].mean(axis=0)) ** 2) / (29 * 9)
    assert own / rest > f.isf(1e-6, 9, 29 * 9)
    assert not erratic_poses(readings[:, 1:].reshape(-1, 3), np.tile(np.arange(29), 10)).any()
    # a deterministic instrument: identical readings but for one count at one pose is its resolution, not the robot
    counts = np.zeros((2, 30, 3))
    counts[1, 7, 0] = 0.03175
    alone = erratic_poses(counts.reshape(-1, 3), np.tile(np.arange(30), 2))
    assert alone.tolist() == [False] * 7 + [True] + [False] * 22
    assert not erratic_poses(counts.reshape(-1, 3), np.tile(np.arange(30), 2), instrument_mm=0.05).any()


@pytest.mark.parametrize("seed", [51, 53])  # one start from the documented geometry: pd_6_x 18.9 u, pd_5_x 24.8 u
def test_a_fit_stuck_in_a_wrong_basin_is_never_stored(tmp_path, capsys, protocol, seed):
    run_id = _store_campaign(tmp_path / "bench.db", protocol[0], _readings(protocol, seed, 1, 0.0))
    assert main(["calibrate", str(run_id), "--store", str(tmp_path / "bench.db"), "--json"]) == 0
    stored = json.loads(capsys.readouterr().out)
    z = _z(stored, seed)
    assert max(z.values()) < 5, max(z.items(), key=lambda item: item[1])
    assert stored["search"]["starts"] == 8 and stored["search"]["kept_start"] > 0  # the documented start was stuck


def test_a_weak_parameter_whose_objective_is_flatter_than_its_linearisation_is_stored_within_5_u(
    tmp_path, capsys, protocol
):
    # seed 55 (ideal readings of 0.05 mm, one cycle): every start of the search lands in one basin, whose linearised
    # u of pd_6_x_mm is too small: stored 5.06 u from its truth. Its profile interval is ~1.3x wider, so is its u
    run_id = _store_campaign(tmp_path / "bench.db", protocol[0], _readings(protocol, 55, 1, 0.0))
    assert main(["calibrate", str(run_id), "--store", str(tmp_path / "bench.db"), "--json"]) == 0
    stored = json.loads(capsys.readouterr().out)
    z = _z(stored, 55)
    assert max(z.values()) < 5, max(z.items(), key=lambda item: item[1])
    widened = stored["search"]["profile_widened"]
    assert {"pd_5_x_mm", "pd_6_x_mm"} <= set(widened) and min(widened.values()) > 1.0
    assert widened["pd_6_x_mm"] == pytest.approx(1.29, abs=0.05)
    assert main(["calibrate", str(run_id), "--store", str(tmp_path / "bench.db")]) == 0
    assert "profile likelihood: the objective rises slower than its linearisation along" in capsys.readouterr().out


def test_a_robot_with_play_is_refused_with_the_cycles_that_then_succeed(tmp_path, capsys, protocol):
    # the documented robot's play, 0.6 mm per axis per move: 2 cycles inform too little, and the line says how
    # many cycles would; a campaign of that many is stored, weighted by its measured scatter (reduced chi^2 ~ 1)
    # with the robot's scatter apart from the instrument's figure
    seed = 21
    path = tmp_path / "bench.db"
    short = _store_campaign(path, protocol[0], _readings(protocol, seed, 2, 0.6))
    assert main(["calibrate", str(short), "--store", str(path)]) == 2
    err = capsys.readouterr().err
    assert re.search(r"inform half the parameters from \d+ cycles per pose \(this run: 2\)", err)
    cycles = int(re.search(r"; measure (\d+) cycles per pose \(the plan for a 5x gain", err)[1])
    assert 2 < cycles < 20
    enough = _store_campaign(tmp_path / "enough.db", protocol[0], _readings(protocol, seed, cycles, 0.6))
    assert main(["calibrate", str(enough), "--store", str(tmp_path / "enough.db"), "--json"]) == 0
    stored = json.loads(capsys.readouterr().out)
    campaign = stored["campaign"]
    assert campaign["instrument_uncertainty_mm"] == MICE_MM
    assert campaign["scatter_mm"] == pytest.approx([0.6] * 3, rel=0.2)  # hypot(0.05, 0.6) = 0.602
    assert campaign["cycles_per_pose"] == [cycles] * 30 and campaign["seconds_per_sample"] == 60.0
    assert 0.5 < stored["reduced_chi2"] < 1.5 and max(_z(stored, seed).values()) < 4


def test_the_plan_of_a_linear_model_is_the_closed_form():
    # one parameter with prior sigma 1, one pose read on one axis with derivative 1 and scatter 0.5 per reading:
    # C(n) = 1 / (n / 0.25 + 1); the error at the pose is sqrt(C(n)); with g = 1 and G = 2 it must be <= 1 / (2 sqrt 2)
    # -> n / 0.25 + 1 >= 8 -> n >= 1.75 -> 2 cycles; the validation n_v = ceil(2 * 4 * 0.25 / 1) = 2
    campaign = pose_means(np.array([[1.0], [0.0]]), [0, 0], instrument_mm=0.01)  # scatter sqrt(0.5)
    campaign = type(campaign)(campaign.mean_mm, campaign.uncertainty_mm, campaign.cycles, np.array([0.5]), 1, 0.01)
    assert campaign.uncertainty_mm[0, 0] == pytest.approx(np.sqrt((0.5 + 10 * 0.5) / 11) / np.sqrt(2))
    noise = float(campaign.uncertainty_mm[0, 0])
    plan = plan_campaign(np.ones((1, 1, 1)), campaign, [1.0], before_mm=float(np.hypot(1.0, noise)), target_gain=2)
    assert plan.geometric_error_mm == pytest.approx(1.0)
    assert plan.calibration_cycles == 2 and plan.validation_cycles == 2
    assert plan.ceiling_gain(100) == pytest.approx(1.0 / (0.5 / 10))


def test_two_plausible_geometries_that_command_alike_are_stored_with_uncertainties_that_cover_both(
    tmp_path, capsys, protocol
):
    # seed 14: one start stops with pd_5_x 10 u from its truth at an objective 5.6 above the truth's basin (ideal
    # data); with 0.05 mm of noise the two basins lie within 4 of each other. Their predictions agree within the
    # kept one's k = 2 uncertainty at every one of the workspace's 300 poses, so it is stored (before: refused),
    # with pd_5_x and pd_6_x widened to cover the other: every parameter within 3 of its stated u of the truth
    path = tmp_path / "bench.db"
    run_id = _store_campaign(path, protocol[0], _readings(protocol, 14, 1, 0.0))
    assert main(["calibrate", str(run_id), "--store", str(path), "--json"]) == 0
    stored = json.loads(capsys.readouterr().out)
    ambiguity = stored["ambiguity"]
    assert {"pd_5_x_mm", "pd_6_x_mm"} <= set(ambiguity["widened"]) and ambiguity["workspace_poses"] > 250
    assert ambiguity["workspace_difference_of_k2_uncertainty"] <= 1.0
    rival = ambiguity["rival"]
    for name in ("pd_5_x_mm", "pd_6_x_mm"):  # the stored u covers the rival's value: u'^2 = u^2 + (rival - kept)^2
        assert stored["parameters"][name]["uncertainty"] >= abs(rival[name] - stored["parameters"][name]["value"])
    assert max(_z(stored, 14).values()) < 3
    assert main(["calibrate", str(run_id), "--store", str(path)]) == 0
    assert "ambiguous: a second solution as plausible differs in" in capsys.readouterr().out


def test_two_geometries_that_command_apart_are_refused_naming_the_poses_that_then_resolve_them(
    tmp_path, capsys, protocol
):
    # seed 33: the two solutions lie 0.70 mm apart at a workspace pose where the kept one states 0.2 mm (k = 2): not
    # stored, and the line names the poses; a campaign with those three poses added is stored, honest
    path = tmp_path / "bench.db"
    run_id = _store_campaign(path, protocol[0], _readings(protocol, 33, 1, 0.0))
    assert main(["calibrate", str(run_id), "--store", str(path)]) == 2
    err = capsys.readouterr().err
    assert "two geometries explain the 30 readings about equally well" in err and "nothing stored" in err
    assert re.search(r"pd_[56]_x_mm \(\d+\.\d u\)", err) and "these poses cannot tell them apart" in err
    with Store(path) as store:
        assert store.calibrations() == []
    named = [json.loads(p) for p in re.findall(r"\[[-0-9., ]+\]", err.split("add poses where they differ most: ")[1])]
    assert len(named) == 3
    poses = np.vstack([protocol[0], named])
    more = (poses, np.array([steps_for_pose(p) for p in poses]), modes_of_poses(poses))
    path = tmp_path / "more.db"
    run_id = _store_campaign(path, poses, _readings(more, 33, 1, 0.0))
    assert main(["calibrate", str(run_id), "--store", str(path), "--json"]) == 0
    stored = json.loads(capsys.readouterr().out)
    assert "ambiguity" not in stored and max(_z(stored, 33).values()) < 4


@pytest.mark.parametrize("gain", ["0.5", "1", "inf", "nan"])
def test_a_target_gain_that_is_no_gain_is_one_line(tmp_path, capsys, gain):
    Store(tmp_path / "bench.db").close()  # a store that exists: the refusal is the gain's, not the path's
    assert main(["calibrate", "1", "--target-gain", gain, "--store", str(tmp_path / "bench.db")]) == 2
    assert capsys.readouterr().err == (
        f"bench: error: --target-gain = {float(gain)!r}, expected a number above 1 (the held-out AP before / after)\n"
    )
