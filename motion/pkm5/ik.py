"""Inverse kinematics of the 5-DOF PKM: poses -> six leg lengths |BC| and elevation angles, with limit checks.

The algorithm is 000 §5.3 / App. B.1 (pkm5.md §3.2) with the unified bracket law of pkm5.md §3.3: the bracket angle
of pairs 1-2 and 3-4 is ``atan2(w_E - w_F, u_E - u_F)`` (one formula for the 13 cases of 000 Table 5-1), the legs
5-6 bracket turns with alpha only. The core is written once against :mod:`motion.dual`, so the same code yields
values (plain arrays) and the exact Jacobian (dual numbers).
"""

from __future__ import annotations

import enum
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from motion import dual
from motion.pkm5 import compiled
from motion.pkm5.geometry import DEFAULT_GEOMETRY, Geometry
from motion.sampling import as_rows

__all__ = ["Failure", "IKResult", "inverse_kinematics", "leg_lengths", "bracket_vectors", "as_poses"]


class Failure(enum.IntFlag):
    """Why a pose is not reachable; several flags may be set at once."""

    NONE = 0
    MODE = 1  # alpha and beta both non-zero: compound rotation is not modelled (pkm5.md §1.2)
    ORIENTATION_RANGE = 2  # alpha or beta outside 000 Tables 6-2 / 6-3
    ALPHA_PLANE = 4  # alpha pose off the plane x = 111.31 mm (legs 5-6 plane cannot contain D5 and D6)
    LEG_LENGTH = 8  # |BC| outside the leg window
    TILT = 16  # leg elevation outside the tilt window


def as_poses(poses: ArrayLike, name: str = "poses") -> np.ndarray:
    """Validate and return poses as float64 (N, 5): x, y, z [mm], alpha, beta [rad]."""
    return as_rows(poses, 5, f"{name} (x, y, z [mm], alpha, beta [rad])")


def _rotate(vector: Sequence[Any], ca: Any, sa: Any, cb: Any, sb: Any) -> tuple[Any, Any, Any]:
    """R(beta, alpha) @ vector with R = Ry(beta) Rx(alpha) (000 Eq. 5.4); vector is a constant 3-tuple (of floats,
    or of per-row arrays when many geometries are evaluated in one batch, as the calibration's Jacobian does)."""
    vx, vy, vz = vector
    has_z = bool(np.any(vz))
    t = sa * vy + ca * vz if has_z else sa * vy
    return cb * vx + sb * t, ca * vy - sa * vz if has_z else ca * vy, -sb * vx + cb * t


def _pair_plane(
    x: Any, y: Any, z: Any, trig: tuple[Any, Any, Any, Any], pd: Sequence[Any], oa: Sequence[Any], half_height: Any
) -> tuple[Any, Any, Any, Any]:
    """Pair 1-2 or 3-4: AD in (u, w) and the bracket rotation (cos, sin of lambda - 90 deg)."""
    ca, sa, cb, sb = trig
    dx, dy, dz = _rotate(pd, ca, sa, cb, sb)
    ax, ay, az = x + dx - oa[0], y + dy - oa[1], z + dz - oa[2]
    # E/F = D +/- h * (R e_z); R e_z = (sb ca, -sa, cb ca)
    ex, ey, ez = sb * ca * half_height, -sa * half_height, cb * ca * half_height
    u = dual.hypot(ax, ay)
    u_e = dual.hypot(ax + ex, ay + ey)
    u_f = dual.hypot(ax - ex, ay - ey)
    # u_E - u_F without cancellation: (u_E^2 - u_F^2) / (u_E + u_F)
    du = 4.0 * (ax * ex + ay * ey) / (u_e + u_f)
    dw = 2.0 * ez
    r = dual.hypot(du, dw)
    # lambda = atan2(dw, du); delta = lambda - 90 deg -> cos delta = dw / r, sin delta = -du / r
    return u, az, dw / r, -du / r


def _leg_in_plane(
    u: Any, w: Any, ab: Sequence[Any], cd: Sequence[Any], cos_d: Any, sin_d: Any, with_tilt: bool
) -> tuple[Any, Any]:
    """Inner loop BC = AD - AB - Rot2(delta) CD (000 Eqs. 5.13-5.22): length and elevation angle (or None)."""
    cu = cos_d * cd[0] - sin_d * cd[1]
    cw = sin_d * cd[0] + cos_d * cd[1]
    bu = u - ab[0] - cu
    bw = w - ab[1] - cw
    return dual.hypot(bu, bw), dual.atan2(bw, bu) if with_tilt else None


def leg_lengths(
    x: Any, y: Any, z: Any, alpha: Any, beta: Any, geometry: Geometry = DEFAULT_GEOMETRY, with_tilt: bool = True
) -> tuple[list[Any], list[Any]]:
    """Six leg lengths |BC| and elevation angles phi (rad) as lists of six arrays or duals.

    Accepts arrays (N,) or :class:`motion.dual.Dual` for every coordinate; constants may be plain arrays.
    With ``with_tilt=False`` the angles are skipped (None), which the FK's inner loop does not need.
    """
    g = geometry
    ca, sa, cb, sb = dual.cos(alpha), dual.sin(alpha), dual.cos(beta), dual.sin(beta)
    trig = (ca, sa, cb, sb)
    lengths, tilts = [], []
    for pd, oa in ((g.pd_12_mm, g.oa_12_mm), (g.pd_34_mm, g.oa_34_mm)):
        u, w, cos_d, sin_d = _pair_plane(x, y, z, trig, pd, oa, g.bracket_half_height_mm)
        for ab, cd in ((g.ab_odd_mm, g.cd_odd_mm), (g.ab_even_mm, g.cd_even_mm)):
            length, tilt = _leg_in_plane(u, w, ab, cd, cos_d, sin_d, with_tilt)
            lengths.append(length)
            tilts.append(tilt)
    # legs 5-6: the bracket turns with alpha in alpha mode only (pkm5.md §3.2 step 4b)
    alpha_mode = np.asarray(dual.value(beta)) == 0
    cos_56 = ca * alpha_mode + (1.0 - alpha_mode)
    sin_56 = sa * alpha_mode
    for pd, ab, cd in ((g.pd_5_mm, g.ab_5_mm, g.cd_5_mm), (g.pd_6_mm, g.ab_6_mm, g.cd_6_mm)):
        dx, dy, dz = _rotate(pd, ca, sa, cb, sb)
        ax, ay, az = x + dx - g.oa_56_mm[0], y + dy - g.oa_56_mm[1], z + dz - g.oa_56_mm[2]
        length, tilt = _leg_in_plane(ay, dual.hypot(ax, az), ab, cd, cos_56, sin_56, with_tilt)
        lengths.append(length)
        tilts.append(tilt)
    return lengths, tilts


def bracket_vectors(poses: ArrayLike, geometry: Geometry = DEFAULT_GEOMETRY) -> dict[str, np.ndarray]:
    """Rotated bracket vectors C->D in the pair planes (000 Eqs. 5.25-5.27, App. C.4), each (N, 2) mm.

    Keys ``cd1``, ``cd3`` (pairs 1-2 and 3-4, odd legs), ``cd2``, ``cd4`` (even legs), ``cd5``, ``cd6``.
    These are the constants ``DC1x, DC1z, ...`` that the documents' alpha/beta Newton-Raphson scripts take from the
    known pose (App. B.3.2-B.3.3).
    """
    p = as_poses(poses)
    g = geometry
    x, y, z, alpha, beta = p.T
    trig = (np.cos(alpha), np.sin(alpha), np.cos(beta), np.sin(beta))
    out = {}
    for names, pd, oa in ((("cd1", "cd2"), g.pd_12_mm, g.oa_12_mm), (("cd3", "cd4"), g.pd_34_mm, g.oa_34_mm)):
        _, _, cos_d, sin_d = _pair_plane(x, y, z, trig, pd, oa, g.bracket_half_height_mm)
        for name, cd in zip(names, (g.cd_odd_mm, g.cd_even_mm)):
            out[name] = np.stack([cos_d * cd[0] - sin_d * cd[1], sin_d * cd[0] + cos_d * cd[1]], -1)
    delta = np.where(beta == 0, alpha, 0.0)
    for name, cd in (("cd5", g.cd_5_mm), ("cd6", g.cd_6_mm)):
        out[name] = np.stack(
            [np.cos(delta) * cd[0] - np.sin(delta) * cd[1], np.sin(delta) * cd[0] + np.cos(delta) * cd[1]], -1
        )
    return out


@dataclass(frozen=True)
class IKResult:
    """Leg lengths and angles of N poses, with the limit checks.

    Attributes
    ----------
    poses : ndarray (N, 5)
        The poses asked for: x, y, z [mm], alpha, beta [rad].
    lengths_mm : ndarray (N, 6)
        Leg lengths |B_i C_i| (pin to pin), always finite.
    tilt_rad : ndarray (N, 6)
        Leg elevation angles phi_1..phi_6 (000 App. B.4; the FK tables' theta_1, theta_3, theta_5).
    failure : ndarray (N,) of int
        Bitwise OR of :class:`Failure` flags; 0 where the pose is reachable.
    length_ok, tilt_ok : ndarray (N, 6) of bool
        Per-leg results of the leg-length and tilt windows.
    """

    poses: np.ndarray
    lengths_mm: np.ndarray
    tilt_rad: np.ndarray
    failure: np.ndarray
    length_ok: np.ndarray
    tilt_ok: np.ndarray
    geometry: Geometry

    @property
    def reachable(self) -> np.ndarray:
        return self.failure == 0

    @property
    def tilt_deg(self) -> np.ndarray:
        return np.degrees(self.tilt_rad)

    def reason(self, i: int) -> str | None:
        """A one-line explanation of why pose ``i`` is not reachable, or None."""
        flags = Failure(int(self.failure[i]))
        if not flags:
            return None
        g = self.geometry
        x, _, _, alpha, beta = self.poses[i]
        a_deg, b_deg = np.degrees(alpha), np.degrees(beta)
        parts = []
        if Failure.MODE in flags:
            parts.append(
                f"alpha = {a_deg:.4g} deg and beta = {b_deg:.4g} deg are both non-zero; compound rotation "
                "(with its parasitic gamma) is not modelled, expected one of translation, "
                "translation + alpha, translation + beta"
            )
        if Failure.ORIENTATION_RANGE in flags:
            parts.append(
                f"alpha = {a_deg:.4g} deg / beta = {b_deg:.4g} deg outside alpha {list(g.alpha_range_deg)} "
                f"deg, beta {list(g.beta_range_deg)} deg"
            )
        if Failure.ALPHA_PLANE in flags:
            parts.append(
                f"x = {x:.4f} mm but alpha poses need x = {g.alpha_plane_x_mm:.2f} mm "
                f"(+/- {g.alpha_plane_tolerance_mm} mm) to keep D5, D6 in the legs 5-6 plane"
            )
        for leg in np.flatnonzero(~self.length_ok[i]):
            parts.append(
                f"leg {leg + 1} length {self.lengths_mm[i, leg]:.3f} mm outside "
                f"({g.leg_min_mm[leg]:g}, {g.leg_max_mm[leg]:g}) mm"
            )
        for leg in np.flatnonzero(~self.tilt_ok[i]):
            parts.append(
                f"leg {leg + 1} tilt {self.tilt_deg[i, leg]:.3f} deg outside "
                f"({g.tilt_min_deg[leg]:g}, {g.tilt_max_deg[leg]:g}) deg"
            )
        return "; ".join(parts)

    @cached_property
    def reasons(self) -> np.ndarray:
        """``reason(i)`` for every pose, as an object array ('' where reachable)."""
        return np.array([self.reason(i) or "" for i in range(len(self.failure))], dtype=object)


def inverse_kinematics(
    poses: ArrayLike, geometry: Geometry = DEFAULT_GEOMETRY, *, check_limits: bool = True, engine: str = "auto"
) -> IKResult:
    """Leg lengths for poses of the PKM, batched.

    Parameters
    ----------
    poses : array_like, shape (N, 5)
        x, y, z [mm] of the end-effector centre P in the base frame, alpha (roll about x) and beta (pitch about y)
        [rad]. A single pose may be given as shape (5,).
    geometry : Geometry
        Parameters and limits (default: the documented robot).
    check_limits : bool, keyword-only
        If False, only the mode is checked (for the documents' CAD rows, which ignore the stroke, pkm5.md §6.0).
    engine : {'auto', 'numpy', 'compiled'}, keyword-only
        'numpy' is the reference below; 'compiled' the numba kernel of :mod:`motion.pkm5.compiled` (same lengths
        to the bit, tilts from the same ``arctan2``); 'auto' compiles batches of at least
        ``compiled.COMPILED_MIN_POSES['ik']`` poses when numba is installed, so small calls never load numba.

    Returns
    -------
    IKResult
        ``lengths_mm`` (N, 6), ``tilt_rad`` (N, 6), ``reachable`` (N,), ``failure`` flags and ``reason(i)``.

    Notes
    -----
    Outer loop AD = OP + R PD - OA (000 Eq. 5.5), reduced to the pair plane (Eqs. 5.17-5.19), inner loop
    BC = AD - AB - CD' (Eqs. 5.13-5.22). Translation invariants: L1 = L2, L3 = L4, L5 = L6.

    Examples
    --------
    The full-retraction pose of 001 §IV.A gives the retracted lengths of 001 Table I (184 mm and 192 mm):

    >>> r = inverse_kinematics([87.82, 0, 295.83, 0, 0])
    >>> np.round(r.lengths_mm, 4)
    array([[183.9988, 183.9988, 183.9988, 183.9988, 191.997 , 191.997 ]])

    It sits 1.25 um below the 184 mm window, so it is not reachable:

    >>> bool(r.reachable[0])
    False
    """
    p = as_poses(poses)
    g = geometry
    if compiled.use_compiled(engine, len(p), "ik"):
        return IKResult(p, *compiled.ik_arrays(p, g, check_limits), g)
    x, y, z, alpha, beta = p.T
    lengths, tilts = leg_lengths(x, y, z, alpha, beta, g)
    lengths_mm = np.stack(lengths, -1)
    tilt_rad = np.stack(tilts, -1)

    failure = np.where((alpha != 0) & (beta != 0), int(Failure.MODE), 0)
    n = len(p)
    length_ok = np.ones((n, 6), bool)
    tilt_ok = np.ones((n, 6), bool)
    if check_limits:
        a_lo, a_hi = np.radians(g.alpha_range_deg)
        b_lo, b_hi = np.radians(g.beta_range_deg)
        out_of_range = (alpha < a_lo) | (alpha > a_hi) | (beta < b_lo) | (beta > b_hi)
        off_plane = (alpha != 0) & (np.abs(x - g.alpha_plane_x_mm) > g.alpha_plane_tolerance_mm)
        length_ok = (lengths_mm > np.asarray(g.leg_min_mm)) & (lengths_mm < np.asarray(g.leg_max_mm))
        tilt_ok = (tilt_rad > np.radians(g.tilt_min_deg)) & (tilt_rad < np.radians(g.tilt_max_deg))
        failure = (
            failure
            | np.where(out_of_range, int(Failure.ORIENTATION_RANGE), 0)
            | np.where(off_plane, int(Failure.ALPHA_PLANE), 0)
            | np.where(length_ok.all(1), 0, int(Failure.LEG_LENGTH))
            | np.where(tilt_ok.all(1), 0, int(Failure.TILT))
        )
    return IKResult(p, lengths_mm, tilt_rad, failure, length_ok, tilt_ok, g)
