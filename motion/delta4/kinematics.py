"""Inverse and forward kinematics of the delta-4 (3-DOF 4-RSS), batched over poses.

IK is the closed form per leg with the thesis' "outer knee" branch; FK is either the thesis closed form
(legs 1 and 3 give x, legs 2 and 4 give y, leg 1 gives z) or a Gauss-Newton least-squares fit over all four
ankle spheres that reports how far the four angles disagree. Unreachable or singular poses are reported per
pose with a reason code; outputs stay finite. Reference: ``delta4-lasergrid.md`` §2.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from motion.delta4 import compiled
from motion.delta4.geometry import (
    LEG_OUTWARD,
    LEG_SIDEWAYS,
    NOMINAL,
    Geometry,
    coord_from_servo_deg,
    knees_mm,
)
from motion.errors import MotionInputError
from motion.sampling import as_rows

__all__ = ["IKResult", "FKResult", "inverse_kinematics", "forward_kinematics", "jacobian_deg_per_mm"]

_E_Z = np.array([0.0, 0.0, 1.0])
#: Reason codes, most fundamental first; a pose carries the first that applies.
REASONS = ("out_of_reach", "above_knee", "singular", "servo_limit")


@dataclass(frozen=True)
class IKResult:
    """Per-pose IK result. Unreachable poses carry finite closest-approach values and a reason.

    Attributes
    ----------
    servo_deg : (N, 4) servo angles theta_R, deg
    coord_deg : (N, 4) coordinate angles theta in [0, 360), deg
    knees_mm : (N, 4, 3) knee positions, mm
    knee_angle_deg : (N, 4) knee angle kappa (0 folded, 180 extended), deg
    reachable : (N,) bool
    reason : (N,) object; None, or "out_of_reach", "above_knee", "singular" or "servo_limit", then " (leg i)"
    """

    servo_deg: np.ndarray
    coord_deg: np.ndarray
    knees_mm: np.ndarray
    knee_angle_deg: np.ndarray
    reachable: np.ndarray
    reason: np.ndarray


@dataclass(frozen=True)
class FKResult:
    """Per-pose FK result.

    Attributes
    ----------
    pose_mm : (N, 3) end-effector centre (x0, y0, z0), mm
    residual_mm : (N,) RMS over the legs of |ankle - knee| - R0, mm: 0 for a consistent angle set
    leg_residual_mm : (N, 4) signed per-leg residual |ankle - knee| - R0, mm
    knees_mm : (N, 4, 3) knee positions, mm
    ok : (N,) bool; False where the solution failed (then pose_mm holds the last finite estimate)
    reason : (N,) object; None or a reason ("no_solution", "degenerate", "not_converged")
    """

    pose_mm: np.ndarray
    residual_mm: np.ndarray
    leg_residual_mm: np.ndarray
    knees_mm: np.ndarray
    ok: np.ndarray
    reason: np.ndarray


#: ``pose (N, 3) -> (residual (N, 4), Jacobian (N, 4, 3))`` of a Gauss-Newton solve.
Residuals = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


def _reasons(fail_by_code: list[np.ndarray]) -> np.ndarray:
    """(N,) reason strings from per-code (N, 4) failure masks; first code and first leg win. Whole arrays at a
    time: a loop over the failing poses was most of the time of a workspace sample (20,000 poses, 40 % out of
    reach)."""
    count = fail_by_code[0].shape[0]
    reason = np.full(count, None, dtype=object)
    open_ = np.ones(count, dtype=bool)  # no reason yet
    for code, failed in zip(REASONS, fail_by_code):
        poses = np.flatnonzero(failed.any(axis=1) & open_)
        labels = np.array([f"{code} (leg {leg})" for leg in range(1, failed.shape[1] + 1)], dtype=object)
        reason[poses] = labels[np.argmax(failed[poses], axis=1)]
        open_[poses] = False
    return reason


def inverse_kinematics(points_mm: ArrayLike, geometry: Geometry = NOMINAL) -> IKResult:
    """Servo angles that place the end-effector centre at each point.

    Parameters
    ----------
    points_mm : array_like, (N, 3) or (3,)
        End-effector centre (x0, y0, z0) in the base frame, mm. z points from the EE to the base, so the
        working poses have z0 < 0.
    geometry : Geometry or CalibratedGeometry
        Dimensions and limits; :data:`~motion.delta4.geometry.THESIS` reproduces the document's digits. Anything
        with ``legs()`` (:class:`~motion.delta4.geometry.Legs`) and the two limits: a calibrated geometry
        (:class:`motion.delta4.calibration.CalibratedGeometry`) is solved leg by leg with its own servo axis
        centre, lengths and servo zero (``q = A_i - O_i`` in place of ``P + (n - m) u_i``).

    Returns
    -------
    IKResult
        Reachable means: every leg closes, every knee angle lies inside ``geometry.knee_limits_deg`` and
        every servo angle inside ``geometry.servo_limits_deg``.

    Notes
    -----
    Compact vector form of the thesis IK (reference §2.3, thesis eqs. 4.12-4.15, Appendix B). For leg i with
    outward unit vector u_i and v_i = e_z x u_i:

    .. math::

        r_A = P\\cdot u_i + n,\\quad \\rho^2 = R_0^2 - (P\\cdot v_i)^2,\\quad d = |(r_A - m, z_0)|,

        \\varphi_i = \\operatorname{atan2}(z_0, r_A - m) + \\arccos\\frac{R_1^2 + d^2 - \\rho^2}{2 R_1 d},
        \\qquad \\theta_{Ri} = 45^\\circ - \\varphi_i

    The "+" takes the outer knee (thesis Fig. 27, ``Determine_correct_solution``). Where a leg cannot close,
    the arccos argument is clipped, which gives the arm direction closest to the ankle.

    Examples
    --------
    TV1 of the reference (thesis §8.2.1), IK(-7, 6, -20) cm:

    >>> from motion.delta4.geometry import THESIS
    >>> inverse_kinematics([-70.0, 60.0, -200.0], THESIS).servo_deg.round(4).tolist()
    [[129.3, 126.6058, 73.7283, 78.5895]]
    """
    points = as_rows(points_mm, 3, "points_mm")
    legs = geometry.legs()
    upper, lower = legs.upper_mm, legs.lower_mm
    span = legs.ankles_mm(points) - legs.origin_mm  # (N, 4, 3): ankle minus servo axis centre
    radial = np.einsum("nij,ij->ni", span, LEG_OUTWARD)
    sideways = np.einsum("nij,ij->ni", span, LEG_SIDEWAYS)
    height = span[..., 2]
    projected_sq = lower**2 - sideways**2
    projected = np.sqrt(np.clip(projected_sq, 0.0, None))
    distance = np.hypot(radial, height)
    safe_distance = np.where(distance > 0.0, distance, 1.0)
    cos_spread = (upper**2 + distance**2 - projected**2) / (2.0 * upper * safe_distance)
    out_of_reach = (projected_sq <= 0.0) | (np.abs(cos_spread) > 1.0) | (distance == 0.0)
    elevation = np.arctan2(height, radial) + np.arccos(np.clip(cos_spread, -1.0, 1.0))

    servo = np.mod(45.0 - np.degrees(elevation) - legs.zero_deg + 135.0, 360.0) - 135.0
    coord = coord_from_servo_deg(servo)
    safe_projected = np.where(projected > 0.0, projected, 1.0)
    cos_knee = (upper**2 + projected**2 - distance**2) / (2.0 * upper * safe_projected)
    knee_angle = np.degrees(np.arccos(np.clip(cos_knee, -1.0, 1.0)))
    low, high = geometry.knee_limits_deg
    singular = (knee_angle < low) | (knee_angle > high)
    servo_low, servo_high = geometry.servo_limits_deg
    servo_limit = (servo < servo_low) | (servo > servo_high)

    knees = legs.knees_mm(servo)
    # The FK keeps the root below the knees (thesis §4.3.2 c), so a pose at or above a knee cannot be returned.
    above_knee = points[:, 2:3] >= knees[:, :, 2]
    reason = _reasons([out_of_reach, above_knee, singular, servo_limit])
    return IKResult(
        servo_deg=servo,
        coord_deg=coord,
        knees_mm=knees,
        knee_angle_deg=knee_angle,
        reachable=np.array([r is None for r in reason], dtype=bool),
        reason=reason,
    )


def _closed_form(knees: np.ndarray, geometry: Geometry) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Thesis FK (reference §2.5, thesis eqs. 4.1-4.7): pose (N, 3), ok (N,), reason (N,)."""
    n, k0 = geometry.ankle_offset_mm, geometry.sphere_constant_mm2
    x1, z1 = knees[:, 0, 0], knees[:, 0, 2]
    y2, z2 = knees[:, 1, 1], knees[:, 1, 2]
    x3, z3 = knees[:, 2, 0], knees[:, 2, 2]
    y4, z4 = knees[:, 3, 1], knees[:, 3, 2]
    c1, c2 = 2 * n - 2 * x1, -2 * n * x1 + x1**2 + z1**2
    c3, c4 = -2 * n - 2 * x3, 2 * n * x3 + x3**2 + z3**2
    c5, c6 = -2 * n - 2 * y2, 2 * n * y2 + y2**2 + z2**2
    c7, c8 = 2 * n - 2 * y4, -2 * n * y4 + y4**2 + z4**2
    # Denominators vanish only for inconsistent angle sets (x1 - x3 = 2n, reference §2.4).
    degenerate = (np.abs(c1 - c3) < 1e-9) | (np.abs(c5 - c7) < 1e-9)
    den_x = np.where(degenerate, 1.0, c1 - c3)
    den_y = np.where(degenerate, 1.0, c5 - c7)
    slope_x, offset_x = 2 * (z1 - z3) / den_x, (c4 - c2) / den_x
    slope_y, offset_y = 2 * (z2 - z4) / den_y, (c8 - c6) / den_y
    a = slope_x**2 + slope_y**2 + 1
    b = 2 * slope_x * offset_x + 2 * n * slope_x - 2 * x1 * slope_x + 2 * slope_y * offset_y - 2 * z1
    c = offset_x**2 + 2 * n * offset_x - 2 * x1 * offset_x - 2 * n * x1 + x1**2 + offset_y**2 + z1**2 - k0
    discriminant = b * b - 4 * a * c
    z0 = (-b - np.sqrt(np.clip(discriminant, 0.0, None))) / (2 * a)  # lower root: EE below the knees
    pose = np.stack([slope_x * z0 + offset_x, slope_y * z0 + offset_y, z0], axis=1)
    no_solution = discriminant < 0
    above_knees = z0 >= knees[:, :, 2].min(axis=1)
    reason = np.full(len(z0), None, dtype=object)
    reason[above_knees] = "no_solution (end effector above a knee)"
    reason[no_solution] = "no_solution (discriminant < 0)"
    reason[degenerate] = "degenerate (x1 - x3 or y4 - y2 equals 2n)"
    return pose, reason == None, reason  # noqa: E711 (elementwise)


def _leg_vectors(pose: np.ndarray, knees: np.ndarray, geometry: Geometry) -> np.ndarray:
    """Ankle minus knee per leg, (N, 4, 3) mm."""
    return geometry.legs().ankles_mm(pose) - knees


def _gauss_newton(
    pose: np.ndarray, residual_and_jacobian: Residuals, *, iterations: int, tolerance_mm: float
) -> tuple[np.ndarray, np.ndarray]:
    """Batched Gauss-Newton: ``residual_and_jacobian(pose) -> (r (N, 4), J (N, 4, 3))``; returns pose, converged."""
    converged = np.zeros(len(pose), dtype=bool)
    for _ in range(iterations):
        residual, jac = residual_and_jacobian(pose)
        normal = np.einsum("nki,nkj->nij", jac, jac)
        gradient = np.einsum("nki,nk->ni", jac, residual)
        # det vs (trace/3)^3 flags a near-singular J^T J as cond() would, without an SVD per pose.
        well_posed = np.linalg.det(normal) > 1e-12 * (np.trace(normal, axis1=1, axis2=2) / 3) ** 3
        normal[~well_posed] = np.eye(3)
        step = -np.linalg.solve(normal, gradient[:, :, None])[:, :, 0]
        step[~well_posed] = 0.0
        pose = pose + step
        converged = well_posed & (np.linalg.norm(step, axis=1) < tolerance_mm)
        if converged.all():
            break
    return pose, converged


def _sphere_residuals(knees: np.ndarray, geometry: Geometry) -> Residuals:
    """Cartesian residuals |A_i(p) - K_i| - R0 (mm) and their Jacobian (reference §2.6)."""

    def evaluate(pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        legs = _leg_vectors(pose, knees, geometry)
        length = np.linalg.norm(legs, axis=2)
        return length - geometry.lower_arm_mm, legs / length[:, :, None]

    return evaluate


def _joint_residuals(servo_deg: np.ndarray, geometry: Geometry) -> Residuals:
    """Joint-space residuals IK_i(p) - theta_Ri (deg) and their Jacobian (reference §2.6, "variant")."""

    def evaluate(pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return inverse_kinematics(pose, geometry).servo_deg - servo_deg, jacobian_deg_per_mm(pose, geometry)

    return evaluate


def forward_kinematics(
    servo_deg: ArrayLike,
    geometry: Geometry = NOMINAL,
    *,
    method: str = "least_squares",
    iterations: int = 50,
    tolerance_mm: float = 1e-10,
    engine: str = "auto",
) -> FKResult:
    """End-effector centre from the four servo angles.

    Parameters
    ----------
    servo_deg : array_like, (N, 4) or (4,)
        Servo angles theta_R1..theta_R4, deg (calibrated travel 30-170 deg; not enforced here, measured
        angles may stray).
    geometry : Geometry
    method : {"least_squares", "joint_space", "closed_form"}, keyword-only
        ``"closed_form"`` is the thesis algorithm (reference §2.5): exact on legs 1 and 3, and the residual
        lands on legs 2 and 4. ``"least_squares"`` starts from it and minimises the four sphere residuals,
        which treats the legs alike for measured, quantised or noisy angles (reference §2.6).
        ``"joint_space"`` instead minimises sum_i (IK_i(p) - theta_Ri)^2, which matches an angle-error model
        (e.g. ADC quantisation) directly; its ``residual_mm`` is still the sphere figure.
    iterations, tolerance_mm : keyword-only
        Gauss-Newton limits (least squares only).
    engine : {"auto", "numpy", "compiled"}, keyword-only
        For ``"least_squares"``: the batched numpy fit (the reference), or the same fit pose by pose in the numba
        kernel of :mod:`motion.delta4.compiled`; "auto" compiles large batches when numba is installed.

    Returns
    -------
    FKResult

    Examples
    --------
    TV2 (thesis §8.2.1): FK of the quantised TV1 angles is (-6.9946, 6.0139, -19.9864) cm by the closed form.

    >>> from motion.delta4.geometry import THESIS
    >>> angles = [129.25, 126.5, 73.7, 78.375]
    >>> forward_kinematics(angles, THESIS, method="closed_form").pose_mm.round(3).tolist()
    [[-69.946, 60.139, -199.864]]
    """
    if method not in ("least_squares", "joint_space", "closed_form"):
        raise MotionInputError(f"method = {method!r}, expected 'least_squares', 'joint_space' or 'closed_form'")
    servo = as_rows(servo_deg, 4, "servo_deg")
    knees = knees_mm(servo, geometry)
    pose, ok, reason = _closed_form(knees, geometry)
    if method != "closed_form":
        start = pose.copy()
        # Without a closed-form start, begin one lower-arm length below the knees' centre.
        start[~ok] = knees[~ok].mean(axis=1) - np.array([0.0, 0.0, 0.8 * geometry.lower_arm_mm])
        if method == "least_squares" and compiled.use_compiled(engine, len(servo)):
            pose, converged = compiled.gauss_newton(start, knees, geometry, iterations, tolerance_mm)
        else:
            residuals = (
                _sphere_residuals(knees, geometry) if method == "least_squares" else _joint_residuals(servo, geometry)
            )
            pose, converged = _gauss_newton(start, residuals, iterations=iterations, tolerance_mm=tolerance_mm)
        reason = np.full(len(converged), None, dtype=object)
        reason[~converged] = "not_converged"
        ok = converged
    leg_residual = np.linalg.norm(_leg_vectors(pose, knees, geometry), axis=2) - geometry.lower_arm_mm
    return FKResult(
        pose_mm=pose,
        residual_mm=np.sqrt(np.mean(leg_residual**2, axis=1)),
        leg_residual_mm=leg_residual,
        knees_mm=knees,
        ok=np.asarray(ok, dtype=bool),
        reason=np.asarray(reason, dtype=object),
    )


def jacobian_deg_per_mm(points_mm: ArrayLike, geometry: Geometry = NOMINAL) -> np.ndarray:
    """Servo-angle Jacobian d theta_R / d p, shape (N, 4, 3), deg/mm.

    Notes
    -----
    Differentiating |A_i(p) - K_i(phi_i)|^2 = R0^2 with e_i = A_i - K_i and
    dK_i/dphi = R1(-sin phi_i u_i + cos phi_i e_z) gives d phi_i/dp = e_i^T / (e_i . dK_i/dphi); then
    d theta_R/dp = -d phi/dp. Rows are finite wherever the IK is finite; they grow without bound at the
    singular knee angles 0 and 180 deg.
    """
    result = inverse_kinematics(points_mm, geometry)
    points = as_rows(points_mm, 3, "points_mm")
    legs = geometry.legs()
    spans = legs.ankles_mm(points) - result.knees_mm
    elevation = legs.elevation_rad(result.servo_deg)[..., None]
    knee_rate = legs.upper_mm[:, None] * (-np.sin(elevation) * LEG_OUTWARD + np.cos(elevation) * _E_Z)
    denominator = np.einsum("nki,nki->nk", spans, knee_rate)
    denominator = np.where(np.abs(denominator) > 1e-12, denominator, np.copysign(1e-12, denominator))
    return -np.degrees(spans / denominator[:, :, None])
