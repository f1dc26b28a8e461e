"""The redundant revolute joint of the 3-PRUS: joint angles (x2, x3, x4) for a given link direction.

In the paper's Eq. (11) geometry the actuated revolute axis and both universal-joint axes pass through one
point, so the link direction u = Ry(x2) Rx(x3) Rz(x4) e_x fixes only two of the three angles: x2 is
redundant with the passive U joint and does not move the platform (reference §2.2, §4.3). A *convention*
picks x2; this module implements the reference's conventions and its closed-form existence test.
"""

from __future__ import annotations

import numpy as np

from motion.errors import MotionInputError

__all__ = ["CONVENTIONS", "universal_from_revolute", "existence_margin", "revolute_angles"]

#: Names accepted by :func:`revolute_angles`; ``clip`` is the default.
CONVENTIONS = ("clip", "x3_zero", "x2_zero", "balanced", "fixed")


def _split(u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """phi = atan2(-u_z, u_x) (rad), rho = hypot(u_x, u_z) and |u_y| of unit link directions (..., 3)."""
    return np.arctan2(-u[..., 2], u[..., 0]), np.hypot(u[..., 0], u[..., 2]), np.abs(u[..., 1])


def universal_from_revolute(u: np.ndarray, x2_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(x3, x4) in rad with Ry(x2) Rx(x3) Rz(x4) e_x = u, on the solution with cos x3 > 0 (reference §4.3).

    v = Ry(-x2) u; sigma = sign(v_y); x4 = sigma atan2(hypot(v_y, v_z), v_x); x3 = atan2(sigma v_z, sigma v_y),
    and x3 = 0 where x4 = 0 (x3 then only spins the link and is idle).
    """
    c2, s2 = np.cos(x2_rad), np.sin(x2_rad)
    vx, vy, vz = c2 * u[..., 0] - s2 * u[..., 2], u[..., 1], s2 * u[..., 0] + c2 * u[..., 2]
    sigma = np.where(vy >= 0, 1.0, -1.0)
    lateral = np.hypot(vy, vz)
    x4 = sigma * np.arctan2(lateral, vx)
    x3 = np.where(lateral < 1e-12, 0.0, np.arctan2(sigma * vz, sigma * vy))
    return x3, x4


def existence_margin(u: np.ndarray, limit_rad: float, actuated_limit_rad: float) -> np.ndarray:
    """L2 + delta_max - |phi| (rad): >= 0 iff some |x2| <= L2 has |x3|, |x4| <= L (reference §4.3).

    delta_max = min(arccos(cos L / rho), arcsin(min(1, |u_y| tan L / rho))); directions with |u_y| > sin L
    get a negative margin (-(|u_y| - sin L) - 1, to stay finite and ordered).
    """
    phi, rho, uy = _split(u)
    rho = np.maximum(rho, 1e-300)
    delta_max = np.minimum(
        np.arccos(np.clip(np.cos(limit_rad) / rho, -1.0, 1.0)),
        np.arcsin(np.clip(uy * np.tan(limit_rad) / rho, 0.0, 1.0)),
    )
    margin = actuated_limit_rad + delta_max - np.abs(phi)
    return np.where(uy <= np.sin(limit_rad), margin, np.sin(limit_rad) - uy - 1.0)


def _balanced_x2(phi: np.ndarray, rho: np.ndarray, uy: np.ndarray) -> np.ndarray:
    """x2 minimising max(|x2|, |x3|, |x4|): bisection of |phi| - t = h(t) (reference §4.3, ``balanced``)."""
    magnitude = np.abs(phi)
    low, high = np.zeros_like(phi), np.minimum(magnitude, np.pi / 2)
    for _ in range(60):
        t = 0.5 * (low + high)
        h = np.maximum(
            np.arctan2(np.sqrt(np.clip(1 - (rho * np.cos(t)) ** 2, 0, None)), rho * np.cos(t)),
            np.arctan2(rho * np.sin(t), uy),
        )
        below = magnitude - t > h
        low, high = np.where(below, t, low), np.where(below, high, t)
    t = np.where(magnitude <= np.arcsin(np.clip(uy, 0, 1)), 0.0, 0.5 * (low + high))
    return np.sign(phi) * (magnitude - t)


def revolute_angles(
    u: np.ndarray, convention: str, actuated_limit_rad: float, fixed_x2_rad: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x2, x3, x4) in rad for unit link directions u (..., 3) under a convention.

    ``clip``: x2 = clip(phi, +-L2), within range exactly when the existence test passes. ``x3_zero``: x2 = phi.
    ``x2_zero``: x2 = 0 (the R actuator idle). ``balanced``: minimises the largest angle. ``fixed``: x2 given
    (e.g. held while the R actuators are locked).
    """
    phi, rho, uy = _split(u)
    if convention == "clip":
        x2 = np.clip(phi, -actuated_limit_rad, actuated_limit_rad)
    elif convention == "x3_zero":
        x2 = phi
    elif convention == "x2_zero":
        x2 = np.zeros_like(phi)
    elif convention == "balanced":
        x2 = _balanced_x2(phi, rho, uy)
    elif convention == "fixed":
        if fixed_x2_rad is None:
            raise MotionInputError("revolute_convention = 'fixed' needs fixed_revolute_deg (N, 3), got None")
        x2 = np.broadcast_to(np.asarray(fixed_x2_rad, dtype=float), phi.shape)
    else:
        raise MotionInputError(f"revolute_convention = {convention!r}, expected one of {', '.join(CONVENTIONS)}")
    x3, x4 = universal_from_revolute(u, x2)
    if convention == "x3_zero":
        x3 = np.zeros_like(x3)  # exact, instead of the +-pi pair atan2 may return when x4 < 0
        x4 = np.arcsin(np.clip(u[..., 1], -1, 1))
    return x2, x3, x4
