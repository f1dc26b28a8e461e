"""Length Jacobian of the PKM and a singularity-proximity index.

The Jacobian dL/dq is exact (forward-mode dual numbers through the IK of :mod:`motion.pkm5.ik`), not a finite
difference; tests compare it with central differences.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from motion import dual
from motion.model import column_conditioning
from motion.pkm5.geometry import DEFAULT_GEOMETRY, Geometry
from motion.pkm5.ik import as_poses, leg_lengths

__all__ = ["jacobian", "SingularityProximity", "singularity_proximity", "mode_columns"]


def jacobian(poses: ArrayLike, geometry: Geometry = DEFAULT_GEOMETRY) -> np.ndarray:
    """dL_i/dq_j of the six leg lengths with respect to the pose, batched.

    Parameters
    ----------
    poses : array_like, shape (N, 5)
        x, y, z [mm], alpha, beta [rad].

    Returns
    -------
    ndarray, shape (N, 6, 5)
        Columns d/dx, d/dy, d/dz [mm/mm], d/dalpha, d/dbeta [mm/rad]. The alpha column at beta = 0 includes the
        legs 5-6 bracket turning with alpha (alpha mode); at beta != 0 that bracket is fixed (beta mode).
    """
    p = as_poses(poses)
    x, y, z, alpha, beta = dual.seed(p)
    lengths, _ = leg_lengths(x, y, z, alpha, beta, geometry=geometry)
    return np.stack([length.grad for length in lengths], 1)


def mode_columns(poses: ArrayLike) -> np.ndarray:
    """Which pose columns move in each pose's mode, (N, 5) bool: x, y, z always; alpha or beta if non-zero."""
    p = as_poses(poses)
    cols = np.ones((len(p), 5), bool)
    cols[:, 3] = p[:, 3] != 0
    cols[:, 4] = p[:, 4] != 0
    return cols


@dataclass(frozen=True)
class SingularityProximity:
    """Conditioning of the length Jacobian restricted to the pose's mode (pkm5.md §5.2).

    Attributes
    ----------
    sigma_min : ndarray (N,)
        Smallest singular value of dL/dq with angles in degrees [mm/mm or mm/deg]. Near 0: some combination of the
        mode's pose variables barely changes any leg length (forward-type singularity).
    inverse_condition : ndarray (N,)
        sigma_min / sigma_max, in [0, 1].
    """

    sigma_min: np.ndarray
    inverse_condition: np.ndarray


def singularity_proximity(poses: ArrayLike, geometry: Geometry = DEFAULT_GEOMETRY) -> SingularityProximity:
    """Smallest singular value and inverse condition number of the mode-restricted length Jacobian.

    The Jacobian columns are x, y, z and, in alpha or beta mode, that angle in degrees (pkm5.md §5.2: "lengths in
    mm, position in mm, angle in degrees"). The spec's reference ranges: Table A.8 (translation) 0.397-0.463,
    Table A.10 (beta) 0.023-0.406; below about 0.05 the FK becomes ill-conditioned.
    """
    p = as_poses(poses)
    jac = jacobian(p, geometry) * np.array([1, 1, 1, np.pi / 180, np.pi / 180])
    return SingularityProximity(*column_conditioning(jac, mode_columns(p)))
