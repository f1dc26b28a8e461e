"""The compiled (numba) PKM kernels against the numpy reference: same lengths, tilts, flags and FK poses.

The first run in a fresh checkout compiles the kernels (numba's cache, ``cache=True``, keeps them for later runs).
"""

import subprocess
import sys

import numpy as np
import pytest
from pkm5_tables import LENGTHS, fk_table, ik_table

from motion import pkm5
from motion.errors import MotionInputError
from motion.pkm5 import compiled

pytest.importorskip("numba", reason="numba (the optional 'fast' extra) is not installed")

MODES = ("translation", "alpha", "beta")


def random_poses(n, seed):
    """Poses in and around the workspace box, every mode, with both angles set on some rows (the MODE flag)."""
    rng = np.random.default_rng(seed)
    poses = np.column_stack(
        [rng.uniform(40, 240, n), rng.uniform(-140, 140, n), rng.uniform(255, 360, n), np.zeros(n), np.zeros(n)]
    )
    kind = rng.integers(0, 4, n)
    poses[kind == 1, 0] = 111.31 + rng.uniform(-0.1, 0.1, (kind == 1).sum())
    poses[(kind == 1) | (kind == 3), 3] = rng.uniform(-0.7, 0.7, ((kind == 1) | (kind == 3)).sum())
    poses[(kind == 2) | (kind == 3), 4] = rng.uniform(-0.7, 0.5, ((kind == 2) | (kind == 3)).sum())
    return poses


def assert_same_ik(poses, geometry=pkm5.DEFAULT_GEOMETRY, check_limits=True):
    reference = pkm5.inverse_kinematics(poses, geometry, check_limits=check_limits, engine="numpy")
    fast = pkm5.inverse_kinematics(poses, geometry, check_limits=check_limits, engine="compiled")
    np.testing.assert_allclose(fast.lengths_mm, reference.lengths_mm, rtol=0, atol=1e-12)
    np.testing.assert_allclose(fast.tilt_rad, reference.tilt_rad, rtol=0, atol=1e-14)
    np.testing.assert_array_equal(fast.failure, reference.failure)
    np.testing.assert_array_equal(fast.length_ok, reference.length_ok)
    np.testing.assert_array_equal(fast.tilt_ok, reference.tilt_ok)
    return reference, fast


@pytest.mark.parametrize("mode", MODES)
def test_ik_matches_numpy_on_the_dissertation_tables(mode):
    df, poses = ik_table(mode)
    reference, fast = assert_same_ik(poses, check_limits=False)
    np.testing.assert_allclose(fast.lengths_mm, df[LENGTHS].to_numpy(), atol=0.011)  # the tables' 0.01 mm print


def test_ik_matches_numpy_on_random_poses_with_every_failure_flag():
    # 10,000 poses cross the kernel's 2,048-pose blocks, the last one partial; all five flags occur
    reference, fast = assert_same_ik(random_poses(10_000, seed=17))
    seen = np.bitwise_or.reduce(reference.failure)
    assert seen == int(
        pkm5.Failure.MODE
        | pkm5.Failure.ORIENTATION_RANGE
        | pkm5.Failure.ALPHA_PLANE
        | pkm5.Failure.LEG_LENGTH
        | pkm5.Failure.TILT
    )
    assert 0.05 < reference.reachable.mean() < 0.9
    # translation lengths are the same IEEE operations in the same order: equal to the bit
    translation = (random_poses(10_000, seed=17)[:, 3:] == 0).all(1)
    np.testing.assert_array_equal(fast.lengths_mm[translation], reference.lengths_mm[translation])


def test_ik_in_tasks_of_blocks_matches_numpy_across_task_and_block_edges():
    # two full tasks and a short one ending in a partial block (on the thread pool where there are several CPUs):
    # every row written once, in place
    kernels = compiled._kernels()
    n = 2 * compiled._IK_TASK_BLOCKS * kernels.IK_BLOCK + kernels.IK_BLOCK + 7
    poses = random_poses(n, seed=29)
    reference, fast = assert_same_ik(poses)
    assert fast.lengths_mm.flags.c_contiguous and fast.failure.dtype == np.int64
    np.testing.assert_array_equal(pkm5.inverse_kinematics(poses[-9:], engine="compiled").tilt_rad, fast.tilt_rad[-9:])


def test_an_oversized_ik_block_is_refused_not_written_past_its_scratch():
    kernels = compiled._kernels()
    inputs, outputs = np.empty(kernels.IN_ROWS * kernels.IK_BLOCK), np.empty(kernels.OUT_ROWS * kernels.IK_BLOCK)
    packed = compiled.pack_geometry(pkm5.DEFAULT_GEOMETRY)
    with pytest.raises(ValueError, match="at most IK_BLOCK poses"):
        kernels.ik_values(np.zeros((kernels.IK_BLOCK + 1, 5)), packed, inputs, outputs)
    with pytest.raises(ValueError, match="at most IK_BLOCK poses"):
        kernels.ik_values(np.zeros((4, 5)), packed, inputs[:-1], outputs)
    flat, flags = np.empty(6 * 4), np.empty(4, np.int64)
    with pytest.raises(ValueError, match="6 values a pose"):
        kernels.ik_limits(inputs, outputs, packed, True, flat[:-1], flat, flags, flat.astype(bool), flat.astype(bool))
    with pytest.raises(ValueError, match="at most IK_BLOCK poses"):
        kernels.ik_limits(inputs, outputs[:-1], packed, True, flat, flat, flags, flat.astype(bool), flat.astype(bool))


def test_ik_matches_numpy_for_another_geometry():
    # non-zero z in the joint vectors takes the other branch of the rotation; other brackets and windows
    geometry = pkm5.DEFAULT_GEOMETRY.replace(
        pd_12_mm=(-19.0, -33.0, 2.5),
        pd_5_mm=(38.0, -25.0, -1.5),
        bracket_half_height_mm=10.0,
        cd_odd_mm=(44.0, 39.0),
        leg_min_mm=(180, 180, 180, 180, 190, 190),
    )
    assert_same_ik(random_poses(2_000, seed=3), geometry)


def fk_inputs():
    poses = pkm5.sample_reachable(600, kinds=("constant-orientation", "alpha", "beta"), seed=5)
    return poses, pkm5.inverse_kinematics(poses).lengths_mm


def assert_same_fk(lengths, pose_atol=1e-9, **kwargs):
    reference = pkm5.forward_kinematics(lengths, engine="numpy", **kwargs)
    fast = pkm5.forward_kinematics(lengths, engine="compiled", **kwargs)
    np.testing.assert_allclose(fast.pose, reference.pose, rtol=0, atol=pose_atol)
    np.testing.assert_array_equal(fast.converged, reference.converged)
    np.testing.assert_array_equal(fast.mode, reference.mode)
    np.testing.assert_allclose(fast.residual_mm, reference.residual_mm, rtol=0, atol=1e-9)
    return reference, fast


def test_fk_matches_numpy_on_reachable_poses_of_every_mode():
    poses, lengths = fk_inputs()
    reference, fast = assert_same_fk(lengths)
    assert set(reference.mode) == set(MODES)
    assert fast.converged.all()
    np.testing.assert_allclose(fast.pose, poses, atol=1e-7)
    # the same LM steps: iteration counts agree except where rounding flips a step-size test
    assert (fast.iterations == reference.iterations).mean() > 0.98


@pytest.mark.parametrize("mode", MODES)
def test_fk_matches_numpy_on_the_dissertation_fk_tables(mode):
    # lengths printed to 0.01 mm are not exactly consistent in alpha and beta mode: the least-squares minimum is
    # flat (residual ~1e-3 mm), the stopping rule max|dq| < 1e-9 leaves its position uncertain to ~1e-8 mm and
    # rounding can change the iteration counts
    df, poses = fk_table(mode)
    reference, fast = assert_same_fk(
        df[LENGTHS].to_numpy(), pose_atol=1e-9 if mode == "translation" else 1e-7, mode=mode
    )
    np.testing.assert_allclose(fast.pose[:, :3], poses[:, :3], atol=0.5)


def test_fk_with_initial_pose_and_a_tight_iteration_cap_matches_numpy():
    poses, lengths = fk_inputs()
    assert_same_fk(lengths[:200], initial_pose=poses[:200] + [0.5, -0.5, 0.5, 0, 0], max_iter=3)


def test_the_per_pose_entry_point_gives_the_batched_answer():
    poses, lengths = fk_inputs()
    batched = pkm5.forward_kinematics(lengths[:20], engine="compiled", mode="translation")
    packed, restarts = compiled.pack_geometry(pkm5.DEFAULT_GEOMETRY), compiled.restart_table("translation")
    for i in range(20):
        q = np.array([[150.0, 0.0, 300.0, 0.0]])
        cost, _, _ = compiled.fk_pose(lengths[i : i + 1], q, compiled.MODE_CODES["translation"], restarts, packed)
        assert np.sqrt(cost[0] / 6) == pytest.approx(batched.residual_mm[i], abs=1e-9)
        if batched.converged[i]:
            np.testing.assert_allclose(q[0, :3], batched.pose[i, :3], atol=1e-9)


def test_an_unknown_engine_is_refused_in_one_line():
    with pytest.raises(MotionInputError, match=r"engine = 'fortran', expected one of \['auto', 'numpy', 'compiled'\]"):
        pkm5.inverse_kinematics([150, 0, 300, 0, 0], engine="fortran")
    with pytest.raises(MotionInputError, match="engine = 'gpu'"):
        pkm5.forward_kinematics([200] * 6, engine="gpu")


def test_small_batches_and_importing_motion_do_not_load_numba():
    code = (
        "import sys; from motion import pkm5; "
        "pkm5.inverse_kinematics([[150, 0, 300, 0, 0]] * 1000); pkm5.forward_kinematics([[200] * 6] * 10); "
        "print('numba' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_auto_dispatches_large_batches_to_the_compiled_kernel():
    poses = np.tile([150.0, 0.0, 300.0, 0.0, 0.0], (compiled.COMPILED_MIN_POSES["ik"], 1))
    assert compiled.use_compiled("auto", len(poses), "ik")
    assert not compiled.use_compiled("auto", len(poses) - 1, "ik")
    np.testing.assert_array_equal(
        pkm5.inverse_kinematics(poses).lengths_mm[:2], pkm5.inverse_kinematics(poses[:2], engine="numpy").lengths_mm
    )
