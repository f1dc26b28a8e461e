"""The simulated PKM5 plant: one warm-started FK per move, computed when the move is accepted.

The reference is the plant as it was: every move solved with the default restarts of
``motion.pkm5.forward_kinematics`` (``retry_above_mm = 1e-9``, which the perturbed legs' 0.1-0.2 mm residual always
exceeds). The fast path must attain the same poses, and a prepared move must equal an unprepared one bit for bit.
"""

import numpy as np
import pytest

from bench.errors import ConfigError
from bench.robots import pkm5_kinematics as kin
from bench.robots import pkm5_wire as wire
from bench.simulators import pkm5_plant
from bench.simulators.error_model import ErrorModel
from bench.simulators.pkm5 import HOME_STEPS, Pkm5SimDevice
from bench.simulators.plant import Plant
from motion import pkm5

# ISO cube of the demo (P1..P5) in cycle order, then poses of the alpha and beta modes (mm, deg)
CUBE = [
    (110.0, 0.0, 320.0, 0, 0),
    (126.16, -16.16, 336.16, 0, 0),
    (126.16, 16.16, 336.16, 0, 0),
    (93.84, 16.16, 303.84, 0, 0),
    (93.84, -16.16, 303.84, 0, 0),
]
ALPHA = [(111.31, -20, 310, 5, 0), (111.31, 10, 315, -4, 0)]
BETA = [(110, 0, 320, 0, 5), (120, 5, 325, 0, -5), (105, -10, 315, 0, 8)]


def reference_plant(seed: int) -> Plant:
    """The plant before issue 17: warm start plus every restart on every move."""
    geometry = pkm5.DEFAULT_GEOMETRY

    def forward(lengths, commanded, previous):
        mode = pkm5.detect_mode(commanded[None, :], 1e-3)[0]
        start = None if previous is None else np.r_[previous[:3], np.radians(previous[3:])]
        fk = pkm5.forward_kinematics(lengths[None, :], geometry, initial_pose=start, mode=mode, residual_tol_mm=2.0)
        return kin.pose_deg_from_rad(fk.pose[0]) if fk.converged[0] else None

    model = ErrorModel.draw(pkm5_plant.PKM5_ERRORS, 6, seed, np.asarray(geometry.leg_length_offset_mm))
    home = pkm5.forward_kinematics(geometry.home_lengths_mm[None, :], geometry)
    return Plant(
        lambda steps: pkm5.steps_to_lengths(steps[None, :], geometry)[0],
        forward,
        model,
        kin.pose_deg_from_rad(home.pose[0]),
        seed,
    )


def steps_of(poses) -> list[np.ndarray]:
    return [np.array(kin.steps_for_pose(p)) for p in poses]


def campaign_steps(cycles: int) -> list[np.ndarray]:
    return steps_of(CUBE * cycles + ALPHA * 2 + BETA)


@pytest.mark.parametrize("seed", [1, 7])
def test_warm_started_plant_attains_the_poses_of_the_restarting_one(seed):
    fast, reference = pkm5_plant.build_plant(seed), reference_plant(seed)
    loads = [0.0, 0.0, 1.5]
    poses = CUBE * 6 + ALPHA * 2
    attained = np.array([fast(steps, loads[i % 3]) for i, steps in enumerate(steps_of(poses))])
    expected = np.array([reference(steps, loads[i % 3]) for i, steps in enumerate(steps_of(poses))])
    assert np.abs(attained - expected).max() < 1e-6  # mm and deg; measured 3e-9
    assert np.abs(attained[:, :3] - np.array([p[:3] for p in poses])).max() > 0.1  # the errors are applied


def test_beta_moves_stay_on_the_branch_the_robot_is_on():
    # The restarts keep the lowest residual; for perturbed beta-mode legs that can be another assembly branch
    # (seed 1, pose (110, 0, 320, 0, 5): x 3.9 mm, beta 36 deg). The warm start follows the robot's own branch.
    for seed in (1, 7):
        fast = pkm5_plant.build_plant(seed)
        for steps, pose in zip(steps_of((CUBE + BETA) * 3), (CUBE + BETA) * 3):
            attained = fast(steps, 0.0)
            assert np.abs(attained - np.array(pose, dtype=float)).max() < 4.0  # the error model's size, mm / deg


def test_a_prepared_move_returns_exactly_what_the_call_would_have():
    prepared, plain = pkm5_plant.build_plant(3), pkm5_plant.build_plant(3)
    for i, steps in enumerate(campaign_steps(2)):
        prepared.prepare(steps, 0.5)
        if i % 4 == 3:  # a move stopped short: the prepared target is never reached, the pose comes from the stop
            steps = steps - 40
        np.testing.assert_array_equal(prepared(steps, 0.5), plain(steps, 0.5))
        np.testing.assert_array_equal(prepared.true_joints, plain.true_joints)


def test_a_prepared_move_with_another_load_is_recomputed():
    prepared, plain = pkm5_plant.build_plant(4), pkm5_plant.build_plant(4)
    steps = np.array(kin.steps_for_pose(CUBE[1]))
    prepared.prepare(steps, 0.0)
    np.testing.assert_array_equal(prepared(steps, 2.0), plain(steps, 2.0))


class CountingPlant(Plant):
    def __init__(self, plant: Plant) -> None:
        self.__dict__.update(plant.__dict__)
        self.solves = 0
        inner = self.forward

        def forward(*args):
            self.solves += 1
            return inner(*args)

        self.forward = forward


def test_done_is_sent_without_solving_the_kinematics_once_the_move_was_prepared():
    plant = CountingPlant(pkm5_plant.build_plant(2))
    device = Pkm5SimDevice(plant, speed_factor=1000.0)
    device.tick(0.0)
    device.feed(wire.encode_line("ENABLE #1"), 0.0)
    target = kin.steps_for_pose(CUBE[2])
    reply = device.feed(wire.encode_line(f"MOVE {' '.join(map(str, target))} 1000 #2"), 0.0)
    assert wire.decode_line(reply.strip()).startswith("OK #2 MOVE")
    before = plant.solves
    device.idle(0.0)  # the event loop, after sending OK: the end pose is solved during the move
    assert plant.solves == before + 1
    done = device.tick(10.0)
    assert wire.decode_line(done.strip()) == f"DONE #2 {' '.join(map(str, target))}"
    assert plant.solves == before + 1  # DONE did not wait for a solve
    expected = pkm5_plant.build_plant(2)
    expected(np.array(HOME_STEPS), 0.0)  # the device's power-up pose
    np.testing.assert_array_equal(device.true_pose, expected(np.array(target), 0.0))


@pytest.mark.skipif(pkm5_plant.plant_engine() != "compiled", reason="numba is not installed")
def test_the_compiled_plant_attains_the_poses_of_the_numpy_reference():
    # the simulator solves each move with the compiled kernel when numba is installed (0.3 ms a move against 7 ms)
    compiled, reference = pkm5_plant.build_plant(4, engine="compiled"), pkm5_plant.build_plant(4, engine="numpy")
    for steps in campaign_steps(3):
        # the same LM steps; the stop at step_tol 1e-7 leaves them about 1e-9 mm apart (measured 1.1e-9 at most)
        np.testing.assert_allclose(compiled(steps, 0.5), reference(steps, 0.5), rtol=0, atol=1e-7)  # mm, deg
        np.testing.assert_array_equal(compiled.true_joints, reference.true_joints)


def test_a_plant_engine_that_does_not_exist_is_refused_by_name():
    with pytest.raises(ConfigError, match="engine = 'fortran', expected one of"):
        pkm5_plant.build_plant(4, engine="fortran")


def test_the_simulator_starts_the_plants_deferred_work_once_built_waiting_as_long_as_told():
    started = []
    plant = Plant(
        lambda steps: steps.astype(float),
        lambda joints, commanded, start: np.zeros(5),
        ErrorModel.ideal(6, 5),
        np.zeros(5),
        0,
        warm_up=started.append,
    )
    device = Pkm5SimDevice(plant, speed_factor=1000.0, kernel_wait_s=6.0)
    assert started == []  # building the device does not start it
    device.ready()  # the event loop, once built and before it serves the port
    device.idle(0.0)
    device.idle(0.1)
    assert started == [6.0]


@pytest.mark.skipif(pkm5_plant.plant_engine() != "compiled", reason="numba is not installed")
def test_a_compiled_plant_waited_for_solves_its_first_warm_move_with_the_kernel(monkeypatch):
    engines = []
    forward = pkm5_plant.pkm5.forward_kinematics

    def recording(*args, **kwargs):
        engines.append(kwargs.get("engine"))
        return forward(*args, **kwargs)

    plant = pkm5_plant.build_plant(4, engine="compiled")
    plant.warm_up(60.0)  # what --kernel-wait-s does before the pty is served (here: until loaded)
    monkeypatch.setattr(pkm5_plant.pkm5, "forward_kinematics", recording)
    for steps in campaign_steps(1)[:2]:
        plant(steps, 0.0)
    assert engines == ["numpy", "compiled"]  # the first pose has no warm start; then the kernel, at once


@pytest.mark.parametrize("value", ["-1", "inf", "nan"])
def test_a_kernel_wait_that_is_not_a_finite_number_of_seconds_is_one_line(value, capsys, monkeypatch):
    from bench.simulators import pkm5 as pkm5_simulator
    from bench.simulators import pty

    def serve(device, args):
        raise AssertionError(f"served with --kernel-wait-s {value}")

    monkeypatch.setattr(pty, "serve", serve)
    assert pkm5_simulator.main(["--kernel-wait-s", value]) == 2
    assert (
        capsys.readouterr()
        .err.strip()
        .endswith(f"error: --kernel-wait-s = {float(value)}, expected a finite number of seconds >= 0")
    )
