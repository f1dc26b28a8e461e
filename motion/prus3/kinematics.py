"""Inverse and forward kinematics of the 3-PRUS, batched over poses.

IK: closed-form slider positions on both branches, with per-leg reach, stroke and revolute-range checks,
and the redundant revolute joint resolved by a documented convention. FK: from complete leg joint sets
(slider, revolute, universal) to corners, then the pose by a frame fit. The six actuators alone do not
determine the pose (three platform freedoms stay free, reference §2, §5.3), so there is no FK from the
actuators; :func:`actuator_residual_mm` checks a measured pose against them instead.
Reference: ``shared/reference/prus3.md`` §4, §5.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from motion.errors import MotionInputError
from motion.prus3.geometry import STAND_IN, Geometry, PoseFit, corners_mm, pose_from_corners
from motion.prus3.revolute import existence_margin, revolute_angles
from motion.sampling import as_rows

__all__ = [
    "IKResult",
    "LEG_REASONS",
    "inverse_kinematics",
    "forward_kinematics",
    "actuator_residual_mm",
    "link_directions",
]

#: Per-leg failure codes, most fundamental first.
LEG_REASONS = ("out_of_reach", "slider_stroke", "revolute_range")


@dataclass(frozen=True)
class IKResult:
    """Per-pose IK result; unreachable poses carry finite closest-approach values.

    Attributes
    ----------
    sliders_mm : (N, 3) slider positions s_i along the rails, mm
    revolute_deg : (N, 3) actuated revolute angles x2 (by the convention), deg
    universal_deg : (N, 3, 2) passive universal angles (x3, x4), deg
    corners_mm : (N, 3, 3) platform corners (S-joint centres), mm
    link_dir : (N, 3, 3) unit link directions u_i
    branch : (N, 3) slider branch sigma_i (+1 or -1)
    ik_margin : (N,) min_i |u_i . d| in [0, 1]: 0 at the IK singularity, where the two branches merge
    leg_reason : (N, 3) object: None or a code of LEG_REASONS
    reachable : (N,) bool
    reason : (N,) object: None or "<code> (leg i)" for the first failing leg
    """

    sliders_mm: np.ndarray
    revolute_deg: np.ndarray
    universal_deg: np.ndarray
    corners_mm: np.ndarray
    link_dir: np.ndarray
    branch: np.ndarray
    ik_margin: np.ndarray
    leg_reason: np.ndarray
    reachable: np.ndarray
    reason: np.ndarray


def _branches(branch: ArrayLike, count: int) -> np.ndarray:
    sigma = np.broadcast_to(np.asarray(branch, dtype=float), (count, 3)) if np.ndim(branch) else None
    if sigma is None or not np.all(np.isin(sigma, (-1.0, 1.0))):
        raise MotionInputError(f"branch = {branch!r}, expected +1/-1 per leg, shape (3,) or (N, 3)")
    return sigma


def _slider_solutions(corners: np.ndarray, geometry: Geometry) -> tuple[np.ndarray, np.ndarray]:
    """Rail coordinate t_i of each corner and r_i^2 = a^2 - h_i^2 (N, 3); s_i = t_i +- r_i."""
    d = np.asarray(geometry.rail_dir, dtype=float)
    w = corners - geometry.rail_offsets_mm
    t = w @ d
    return t, geometry.link_mm**2 - (np.sum(w * w, axis=2) - t**2)


def link_directions(corners: np.ndarray, sliders_mm: np.ndarray, geometry: Geometry) -> np.ndarray:
    """u_i = (K_i - o_i - s_i d) / a, (N, 3, 3)."""
    d = np.asarray(geometry.rail_dir, dtype=float)
    return (corners - geometry.rail_offsets_mm - sliders_mm[..., None] * d) / geometry.link_mm


def inverse_kinematics(
    pose: ArrayLike,
    geometry: Geometry = STAND_IN,
    *,
    branch: ArrayLike = (1, 1, 1),
    revolute_convention: str = "clip",
    fixed_revolute_deg: ArrayLike | None = None,
) -> IKResult:
    """Slider positions and leg joint angles for platform poses.

    Parameters
    ----------
    pose : array_like, (N, 6) or (6,)
        Tip position x, y, z (mm) in {O2} and orientation alpha, beta, gamma (deg), R = Rz(gamma) Ry(beta)
        Rx(alpha).
    geometry : Geometry
    branch : (3,) or (N, 3) of +1/-1, keyword-only
        Slider branch per leg: s_i = t_i + sigma_i r_i. +1 puts the slider further along the rail direction
        than the corner. Three legs give 8 assembly modes.
    revolute_convention : {"clip", "x3_zero", "x2_zero", "balanced", "fixed"}, keyword-only
        How the redundant revolute x2 is chosen (:mod:`motion.prus3.revolute`). Corners, sliders and the slider
        Jacobian do not depend on it. Reachability uses the convention-free existence test.
    fixed_revolute_deg : (N, 3) or (3,), keyword-only
        x2 for ``"fixed"``.

    Notes
    -----
    With w_i = K_i - o_i, t_i = w_i . d, h_i^2 = |w_i|^2 - t_i^2 and r_i^2 = a^2 - h_i^2 (reference §4.2):

    .. math:: s_i = t_i + \\sigma_i \\sqrt{r_i^2}

    Where r_i^2 < 0 the square root is clipped to 0 (the closest slider point) and the leg reports
    ``out_of_reach``; ``slider_stroke`` flags s_i outside the stroke; ``revolute_range`` flags a link
    direction that no (x2, x3, x4) inside the ranges can produce.

    Examples
    --------
    Home pose H of the reference (TV-2, stand-in geometry):

    >>> inverse_kinematics([530.0, 0.0, -600.0, 0.0, 0.0, 0.0]).sliders_mm.round(6).tolist()
    [[702.211937, 991.120186, 832.115747]]
    """
    poses = as_rows(pose, 6, "pose")
    sigma = _branches(branch, len(poses))
    corners, _, _ = corners_mm(poses, geometry)
    t, r_sq = _slider_solutions(corners, geometry)
    sliders = t + sigma * np.sqrt(np.clip(r_sq, 0.0, None))
    u = link_directions(corners, sliders, geometry)
    limit, limit2 = np.radians(geometry.revolute_limit_deg), np.radians(geometry.actuated_limit_deg)
    fixed = None if fixed_revolute_deg is None else np.radians(as_rows(fixed_revolute_deg, 3, "fixed_revolute_deg"))
    x2, x3, x4 = revolute_angles(u, revolute_convention, limit2, fixed)

    low, high = geometry.stroke_mm
    failures = [r_sq < 0, (sliders < low) | (sliders > high), existence_margin(u, limit, limit2) < 0]
    leg_reason = np.full(sliders.shape, None, dtype=object)
    for code, failed in reversed(list(zip(LEG_REASONS, failures))):
        leg_reason[failed] = code
    reason = np.full(len(poses), None, dtype=object)
    for index in np.flatnonzero((leg_reason != None).any(axis=1)):  # noqa: E711 (elementwise)
        leg = int(np.argmax(leg_reason[index] != None))  # noqa: E711
        reason[index] = f"{leg_reason[index, leg]} (leg {leg + 1})"
    return IKResult(
        sliders_mm=sliders,
        revolute_deg=np.degrees(x2),
        universal_deg=np.degrees(np.stack([x3, x4], axis=-1)),
        corners_mm=corners,
        link_dir=u,
        branch=sigma.copy(),
        ik_margin=np.abs(u @ np.asarray(geometry.rail_dir, dtype=float)).min(axis=1),
        leg_reason=leg_reason,
        reachable=np.array([r is None for r in reason], dtype=bool),
        reason=reason,
    )


def _link_unit(x2: np.ndarray, x3: np.ndarray, x4: np.ndarray) -> np.ndarray:
    """Ry(x2) Rx(x3) Rz(x4) e_x = (c2 c4 + s2 s3 s4, c3 s4, c2 s3 s4 - s2 c4), angles in rad."""
    c2, s2, c3, s3, c4, s4 = np.cos(x2), np.sin(x2), np.cos(x3), np.sin(x3), np.cos(x4), np.sin(x4)
    return np.stack([c2 * c4 + s2 * s3 * s4, c3 * s4, c2 * s3 * s4 - s2 * c4], axis=-1)


def forward_kinematics(
    sliders_mm: ArrayLike,
    revolute_deg: ArrayLike,
    universal_deg: ArrayLike,
    geometry: Geometry = STAND_IN,
    *,
    method: str = "kabsch",
) -> PoseFit:
    """Pose from complete leg joint sets: slider s_i, revolute x2 and universal (x3, x4) of every leg.

    Per leg (Eq. 11 corrected, erratum E3): K_i = o_i + s_i d + a Ry(x2) Rx(x3) Rz(x4) e_x; then the frame
    fit of :func:`~motion.prus3.geometry.pose_from_corners`, whose RMS residual tells how consistent the
    measured joints are (0 for an exact set). Shapes: sliders (N, 3) mm, revolute (N, 3) deg,
    universal (N, 3, 2) deg.
    """
    sliders = as_rows(sliders_mm, 3, "sliders_mm")
    x2 = np.radians(as_rows(revolute_deg, 3, "revolute_deg"))
    universal = np.radians(np.asarray(universal_deg, dtype=float).reshape(-1, 3, 2))
    if universal.shape[0] != sliders.shape[0] or not np.all(np.isfinite(universal)):
        raise MotionInputError(f"universal_deg has shape {np.shape(universal_deg)}, expected finite (N, 3, 2)")
    d = np.asarray(geometry.rail_dir, dtype=float)
    u = _link_unit(x2, universal[..., 0], universal[..., 1])
    corners = geometry.rail_offsets_mm + sliders[..., None] * d + geometry.link_mm * u
    return pose_from_corners(corners, geometry, method=method)


def actuator_residual_mm(pose: ArrayLike, sliders_mm: ArrayLike, geometry: Geometry = STAND_IN) -> np.ndarray:
    """Leg-length misfit |K_i - Q_i| - a (N, 3) mm of a measured pose against measured slider positions.

    The six actuators fix only three functions of the pose (reference §5.3, TV-6), so this consistency
    check replaces an "FK from actuators", which would have a 3-D family of answers.
    """
    poses = as_rows(pose, 6, "pose")
    sliders = as_rows(sliders_mm, 3, "sliders_mm")
    corners, _, _ = corners_mm(poses, geometry)
    return np.linalg.norm(link_directions(corners, sliders, geometry), axis=2) * geometry.link_mm - geometry.link_mm
