"""Slider-rate Jacobian of the 3-PRUS and its singularity-proximity measures (reference ``prus3.md`` §6).

The paper's 6 x 6 Jacobian (Eq. 16) cannot exist: three distance constraints give a 3 x 6 map from pose
rates to slider rates, and the revolute actuators do not enter it (erratum E8).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from motion.errors import MotionInputError
from motion.prus3.geometry import STAND_IN, Geometry
from motion.prus3.kinematics import inverse_kinematics
from motion.sampling import as_rows

__all__ = ["SliderJacobian", "slider_jacobian"]


@dataclass(frozen=True)
class SliderJacobian:
    """Slider-rate Jacobian and singularity measures at each pose.

    Attributes
    ----------
    matrix : (N, 3, 6)
        ds/dx. Position columns mm/mm; angle columns mm/rad (Euler rates for ``form="euler"``, angular
        velocity in {O2} for ``form="twist"``).
    ik_margin : (N,) min_i |u_i . d|, 0 at the IK (serial) singularity
    line_singular_values : (N, 3) singular values of the unit leg-line matrix [u_i, (r_i x u_i)/a]; the smallest
        tends to 0 when the three leg lines become dependent
    euler_margin : (N,) |cos beta|, 0 at the Euler-rate singularity
    """

    matrix: np.ndarray
    ik_margin: np.ndarray
    line_singular_values: np.ndarray
    euler_margin: np.ndarray


def slider_jacobian(
    pose: ArrayLike, geometry: Geometry = STAND_IN, *, branch: ArrayLike = (1, 1, 1), form: str = "euler"
) -> SliderJacobian:
    """ds_i/dx for platform poses (N, 6) (mm, deg).

    Notes
    -----
    Differentiating |K_i - o_i - s_i d|^2 = a^2 with dK_i = v + omega x r_i, r_i = K_i - P:

    .. math:: \\dot s_i = \\frac{u_i \\cdot v + (r_i \\times u_i) \\cdot \\omega}{u_i \\cdot d}

    Euler form: omega = E (alpha', beta', gamma'), E = [Rz Ry e_x, Rz e_y, e_z], det E = cos beta.
    At the IK singularity u_i . d = 0 the denominator is kept at +-1e-12 (finite, very large rows).

    Examples
    --------
    d s_i / d P_z = -1 for every leg, because the rails run along -z:

    >>> slider_jacobian([450.0, 150.0, -600.0, 3.0, -4.0, 5.0]).matrix[0, :, 2].tolist()
    [-1.0, -1.0, -1.0]
    """
    if form not in ("euler", "twist"):
        raise MotionInputError(f"form = {form!r}, expected 'euler' or 'twist'")
    poses = as_rows(pose, 6, "pose")
    ik = inverse_kinematics(poses, geometry, branch=branch)
    u = ik.link_dir
    arm = ik.corners_mm - poses[:, None, :3]
    moment = np.cross(arm, u)
    along = u @ np.asarray(geometry.rail_dir, dtype=float)
    along = np.where(np.abs(along) > 1e-12, along, np.copysign(1e-12, along))
    angular = moment
    beta, gamma = np.radians(poses[:, 4]), np.radians(poses[:, 5])
    if form == "euler":
        cb, sb, cg, sg = np.cos(beta), np.sin(beta), np.cos(gamma), np.sin(gamma)
        zero, one = np.zeros_like(cb), np.ones_like(cb)
        euler = np.stack(
            [np.stack([cb * cg, -sg, zero], 1), np.stack([cb * sg, cg, zero], 1), np.stack([-sb, zero, one], 1)], 1
        )
        angular = moment @ euler
    lines = np.concatenate([u, moment / geometry.link_mm], axis=2)
    return SliderJacobian(
        matrix=np.concatenate([u, angular], axis=2) / along[:, :, None],
        ik_margin=ik.ik_margin,
        line_singular_values=np.linalg.svd(lines, compute_uv=False),
        euler_margin=np.abs(np.cos(beta)),
    )
