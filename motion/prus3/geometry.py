"""3-PRUS geometry as data, the rotation convention and the pose <-> platform-corner maps.

The paper's Table 2 lost every dimension; the defaults are the reference's round stand-in values, not a
reconstruction. Reference: ``shared/reference/prus3.md`` §3, §4.1, §5.2 (source: Thomas, Joy, Sudheer,
Chin. J. Mech. Eng. 33 (2020), DOI 10.1186/s10033-020-0433-8).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from motion.errors import MotionInputError

__all__ = [
    "Geometry",
    "STAND_IN",
    "rotation_matrix",
    "euler_deg_from_matrix",
    "corners_mm",
    "pose_from_corners",
    "PoseFit",
]


@dataclass(frozen=True)
class Geometry:
    """Dimensions (mm) and conventions of the 3-PRUS.

    Parameters
    ----------
    link_mm
        a: U-joint centre to S-joint centre (Table 2 "a", value lost; stand-in 600).
    platform_radius_mm
        b: platform circumradius, centroid to corner (Table 2 "b", lost; stand-in 75). Side k = sqrt(3) b.
    rail_spacing_mm
        c: rail spacing (Table 2 "c", lost; stand-in 100). Used when ``rail_y_mm`` is None.
    stroke_mm
        Slider range [low, high] (Table 2 "l" lost; Section 5.1 samples 0-1.2 m).
    tip_offset_mm
        n: tip offset along the platform normal y_P (undefined in the paper; Eq. 14 implies 0).
    corner_angle_deg
        delta of the corner positions (Eq. 14: 30 deg).
    rail_y_mm
        Rail offsets y_i of legs 1-3; default (-c, 0, +c) as in Eq. (11) (Eqs. 5/6 have the opposite signs).
    rail_dir
        Unit rail direction d in {O2}; default (0, 0, -1) as in Eq. (11) (the Appendix implies +z).
    revolute_limit_deg
        L: range +-L of the revolute and universal angles x2, x3, x4 (Section 5.1 samples +-45 deg).
    actuated_revolute_limit_deg
        L2 <= L: optional tighter range of the actuated revolute x2; None means L.
    """

    link_mm: float = 600.0
    platform_radius_mm: float = 75.0
    rail_spacing_mm: float = 100.0
    stroke_mm: tuple[float, float] = (0.0, 1200.0)
    tip_offset_mm: float = 0.0
    corner_angle_deg: float = 30.0
    rail_y_mm: tuple[float, float, float] | None = None
    rail_dir: tuple[float, float, float] = (0.0, 0.0, -1.0)
    revolute_limit_deg: float = 45.0
    actuated_revolute_limit_deg: float | None = None

    def __post_init__(self) -> None:
        for name in ("link_mm", "platform_radius_mm", "rail_spacing_mm"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise MotionInputError(f"Geometry.{name} = {value!r}, expected a finite length > 0 mm")
        low, high = self.stroke_mm
        if not low < high:
            raise MotionInputError(f"Geometry.stroke_mm = {self.stroke_mm!r}, expected (low, high) with low < high")
        if abs(np.linalg.norm(self.rail_dir) - 1.0) > 1e-9:
            raise MotionInputError(f"Geometry.rail_dir = {self.rail_dir!r}, expected a unit vector")
        if not 0 < self.revolute_limit_deg <= 90:
            raise MotionInputError(f"Geometry.revolute_limit_deg = {self.revolute_limit_deg!r}, expected 0 < L <= 90")
        limit2 = self.actuated_revolute_limit_deg
        if limit2 is not None and not 0 < limit2 <= self.revolute_limit_deg:
            raise MotionInputError(f"Geometry.actuated_revolute_limit_deg = {limit2!r}, expected 0 < L2 <= L")

    @property
    def rail_offsets_mm(self) -> np.ndarray:
        """Rail origins o_i = (0, y_i, 0), shape (3, 3) mm."""
        y = self.rail_y_mm if self.rail_y_mm is not None else (-self.rail_spacing_mm, 0.0, self.rail_spacing_mm)
        return np.column_stack([np.zeros(3), np.asarray(y, dtype=float), np.zeros(3)])

    @property
    def platform_corners_mm(self) -> np.ndarray:
        """Corners p_j in the platform frame {P}, shape (3, 3) mm (Eq. 14): an equilateral triangle in x_P-z_P."""
        b, delta = self.platform_radius_mm, math.radians(self.corner_angle_deg)
        return np.array(
            [[b * math.sin(delta), 0, b * math.cos(delta)], [-b, 0, 0], [b * math.sin(delta), 0, -b * math.cos(delta)]]
        )

    @property
    def actuated_limit_deg(self) -> float:
        """L2, the range of x2 (deg)."""
        return self.revolute_limit_deg if self.actuated_revolute_limit_deg is None else self.actuated_revolute_limit_deg


#: The reference's stand-in dimensions (§3.2, §3.3): a = 600, b = 75, c = 100, stroke 0-1200, n = 0 mm.
STAND_IN = Geometry()


def rotation_matrix(angles_deg: np.ndarray) -> np.ndarray:
    """R = Rz(gamma) Ry(beta) Rx(alpha), shape (N, 3, 3), from (alpha, beta, gamma) (N, 3) in degrees.

    Notes
    -----
    This is the convention the paper's explicit corner formulas (Eq. 14) use. Eq. (12) is labelled
    Rz(alpha)Ry(beta)Rx(gamma) and its printed matrix is not a rotation at all (erratum E5).
    """
    a, b, g = np.radians(np.asarray(angles_deg, dtype=float)).T
    ca, sa, cb, sb, cg, sg = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(g), np.sin(g)
    return np.stack(
        [
            np.stack([cg * cb, cg * sb * sa - sg * ca, cg * sb * ca + sg * sa], axis=-1),
            np.stack([sg * cb, sg * sb * sa + cg * ca, sg * sb * ca - cg * sa], axis=-1),
            np.stack([-sb, cb * sa, cb * ca], axis=-1),
        ],
        axis=-2,
    )


def euler_deg_from_matrix(rotation: np.ndarray) -> np.ndarray:
    """(alpha, beta, gamma) (N, 3) deg from R (N, 3, 3): beta = -asin R31, alpha = atan2(R32, R33),
    gamma = atan2(R21, R11). Singular at cos(beta) = 0."""
    beta = -np.arcsin(np.clip(rotation[:, 2, 0], -1.0, 1.0))
    alpha = np.arctan2(rotation[:, 2, 1], rotation[:, 2, 2])
    gamma = np.arctan2(rotation[:, 1, 0], rotation[:, 0, 0])
    return np.degrees(np.stack([alpha, beta, gamma], axis=1))


def corners_mm(pose: np.ndarray, geometry: Geometry = STAND_IN) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Platform corners K_j = P_c + R p_j (N, 3, 3) mm, with R (N, 3, 3) and the tip P (N, 3).

    ``pose`` is (N, 6): tip position x, y, z (mm) and alpha, beta, gamma (deg). P_c = P - n R e_y.
    """
    rotation = rotation_matrix(pose[:, 3:])
    centroid = pose[:, :3] - geometry.tip_offset_mm * rotation[:, :, 1]
    return (
        centroid[:, None, :] + np.einsum("nij,kj->nki", rotation, geometry.platform_corners_mm),
        rotation,
        pose[:, :3],
    )


@dataclass(frozen=True)
class PoseFit:
    """Pose recovered from three corners: ``pose`` (N, 6) mm/deg, ``residual_mm`` (N,) RMS corner misfit."""

    pose: np.ndarray
    residual_mm: np.ndarray


def pose_from_corners(corners: ArrayLike, geometry: Geometry = STAND_IN, *, method: str = "kabsch") -> PoseFit:
    """Platform pose from its three corner positions (N, 3, 3) mm (reference §5.2).

    ``method="closed_form"`` builds the frame from the corners directly (exact corners only):
    x_P = (P_c - K2)/b, z_P = (K1 - K3)/(2 b cos delta), y_P = z_P x x_P. ``method="kabsch"`` (default) is
    the least-squares rotation R = V diag(1, 1, det(V U^T)) U^T from H = sum_j p_j (K_j - P_c)^T = U S V^T,
    which also suits measured corners; the RMS corner residual is the consistency figure.
    """
    points = np.asarray(corners, dtype=float)
    if points.ndim == 2:
        points = points[None]
    if points.ndim != 3 or points.shape[1:] != (3, 3) or not np.all(np.isfinite(points)):
        raise MotionInputError(f"corners has shape {np.shape(corners)}, expected finite (N, 3, 3) mm")
    if method not in ("kabsch", "closed_form"):
        raise MotionInputError(f"method = {method!r}, expected 'kabsch' or 'closed_form'")
    centroid = points.mean(axis=1)
    local = geometry.platform_corners_mm
    if method == "closed_form":
        x_axis = (centroid - points[:, 1]) / geometry.platform_radius_mm
        z_axis = (points[:, 0] - points[:, 2]) / (
            2 * geometry.platform_radius_mm * math.cos(math.radians(geometry.corner_angle_deg))
        )
        rotation = np.stack([x_axis, np.cross(z_axis, x_axis), z_axis], axis=2)
    else:
        h = np.einsum("kj,nki->nji", local, points - centroid[:, None, :])
        u, _, vt = np.linalg.svd(h)
        v = np.swapaxes(vt, 1, 2)
        sign = np.sign(np.linalg.det(v @ np.swapaxes(u, 1, 2)))
        rotation = (
            v
            @ (np.eye(3) * np.stack([np.ones_like(sign), np.ones_like(sign), sign], axis=1)[:, None, :])
            @ np.swapaxes(u, 1, 2)
        )
    fitted = centroid[:, None, :] + np.einsum("nij,kj->nki", rotation, local)
    residual = np.sqrt(np.mean(np.sum((fitted - points) ** 2, axis=2), axis=1))
    tip = centroid + geometry.tip_offset_mm * rotation[:, :, 1]
    return PoseFit(pose=np.concatenate([tip, euler_deg_from_matrix(rotation)], axis=1), residual_mm=residual)
