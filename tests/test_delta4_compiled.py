"""The compiled delta-4 least-squares FK (motion/delta4/compiled.py) against the batched numpy fit."""

import numpy as np
import pytest

from motion import delta4
from motion.delta4 import compiled
from motion.delta4.geometry import THESIS

pytest.importorskip("numba", reason="numba (the optional 'fast' extra) is not installed")


def noisy_angles(n, seed, geometry=delta4.NOMINAL):
    """IK angles of points in the operating box plus 0.275 deg noise (the ADC quantisation of the reference)."""
    rng = np.random.default_rng(seed)
    points = rng.uniform([-60, -60, -230], [60, 60, -130], size=(n, 3))
    return points, delta4.inverse_kinematics(points, geometry).servo_deg + rng.normal(0.0, 0.275, (n, 4))


@pytest.mark.parametrize("geometry", [delta4.NOMINAL, THESIS], ids=["nominal", "thesis"])
def test_compiled_fit_matches_the_numpy_fit(geometry):
    points, angles = noisy_angles(3_000, seed=4, geometry=geometry)
    # and angle sets far from any pose: no closed-form start, some never converge
    angles = np.vstack([angles, np.random.default_rng(5).uniform(30, 170, (300, 4))])
    reference = delta4.forward_kinematics(angles, geometry, engine="numpy")
    fast = delta4.forward_kinematics(angles, geometry, engine="compiled")
    np.testing.assert_array_equal(fast.ok, reference.ok)
    ok = reference.ok
    assert 0.9 < ok.mean() < 1.0
    np.testing.assert_allclose(fast.pose_mm[ok], reference.pose_mm[ok], rtol=0, atol=1e-9)
    np.testing.assert_allclose(fast.residual_mm[ok], reference.residual_mm[ok], rtol=0, atol=1e-9)
    # the noise moves the fitted point by about a millimetre, not more
    assert np.linalg.norm(fast.pose_mm[:3_000] - points, axis=1).mean() < 2.0


def test_exact_angles_give_the_points_back():
    points, _ = noisy_angles(500, seed=6)
    fast = delta4.forward_kinematics(delta4.inverse_kinematics(points).servo_deg, engine="compiled")
    assert fast.ok.all()
    np.testing.assert_allclose(fast.pose_mm, points, atol=1e-9)


def test_auto_compiles_large_least_squares_batches_only():
    assert compiled.use_compiled("auto", compiled.COMPILED_MIN_POSES)
    assert not compiled.use_compiled("auto", compiled.COMPILED_MIN_POSES - 1)
    assert not compiled.use_compiled("numpy", 10**7)
