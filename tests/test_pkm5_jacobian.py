"""Jacobian of the PKM leg lengths and the singularity-proximity index."""

import numpy as np
import pytest
from pkm5_tables import fk_table, ik_table

from motion import pkm5


def central_difference(poses, h=(1e-5, 1e-5, 1e-5, 1e-7, 1e-7)):
    jac = np.empty((len(poses), 6, 5))
    for j, step in enumerate(h):
        delta = np.zeros(5)
        delta[j] = step
        plus = pkm5.inverse_kinematics(poses + delta, check_limits=False).lengths_mm
        minus = pkm5.inverse_kinematics(poses - delta, check_limits=False).lengths_mm
        jac[:, :, j] = (plus - minus) / (2 * step)
    return jac


@pytest.mark.parametrize("mode", ["translation", "alpha", "beta"])
def test_jacobian_matches_central_differences(mode):
    _, poses = ik_table(mode)
    exact = pkm5.jacobian(poses)
    numeric = central_difference(poses)
    # the angle columns are only defined inside the pose's own mode (compound rotation is not modelled)
    cols = [0, 1, 2] + ([3] if mode != "beta" else []) + ([4] if mode != "alpha" else [])
    scale = np.abs(exact[:, :, cols]).max()
    assert np.abs(exact[:, :, cols] - numeric[:, :, cols]).max() / scale < 1e-7


def test_translation_jacobian_has_equal_pair_rows():
    _, poses = ik_table("translation")
    jac = pkm5.jacobian(poses)
    np.testing.assert_allclose(jac[:, 0, :3], jac[:, 1, :3], atol=1e-12)


@pytest.mark.parametrize(
    "table, mode, low, high",
    [
        # pkm5.md §5.2: sigma_min ranges (mm/mm, mm/deg) over the tabulated pose sets
        ("ik", "translation", 0.397, 0.463),
        ("ik", "alpha", 0.201, 0.447),
        ("ik", "beta", 0.023, 0.406),
        ("fk", "translation", 0.350, 0.453),
        ("fk", "alpha", 0.197, 0.415),
        ("fk", "beta", 0.025, 0.454),
    ],
)
def test_sigma_min_ranges(table, mode, low, high):
    _, poses = (ik_table if table == "ik" else fk_table)(mode)
    proximity = pkm5.singularity_proximity(poses)
    assert proximity.sigma_min.min() == pytest.approx(low, abs=6e-4)
    assert proximity.sigma_min.max() == pytest.approx(high, abs=6e-4)
    assert np.all((proximity.inverse_condition > 0) & (proximity.inverse_condition <= 1))


def test_large_positive_beta_is_near_singular():
    """pkm5.md §5.2: sigma_min collapses toward large positive beta (median 0.035 at 15-20 deg)."""
    near = pkm5.singularity_proximity([[110.47, 25.81, 311.94, 0, np.radians(20.18)]]).sigma_min[0]
    far = pkm5.singularity_proximity([[150, 0, 300, 0, np.radians(-25)]]).sigma_min[0]
    assert near < 0.05 < 0.25 < far
