"""Delta-4 geometry as data, and the servo/coordinate angle conventions of the thesis.

All lengths are mm and all public angles degrees. The source document works in cm; multiply its lengths by 10.
Reference: ``shared/reference/delta4-lasergrid.md`` §1.2-§1.6 (thesis §4.3.2, Table 3, §8.1.1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from motion.errors import MotionInputError

__all__ = [
    "Geometry",
    "Legs",
    "NOMINAL",
    "THESIS",
    "LEG_OUTWARD",
    "LEG_SIDEWAYS",
    "ankle_positions",
    "coord_from_servo_deg",
    "servo_from_coord_deg",
    "knees_mm",
]

#: Outward unit vector u_i of each leg in the base frame: legs 1-4 sit at +x, -y, -x, +y (thesis Fig. 20).
LEG_OUTWARD = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
#: v_i = e_z x u_i: the horizontal direction normal to each leg plane.
LEG_SIDEWAYS = np.cross(np.array([0.0, 0.0, 1.0]), LEG_OUTWARD)
#: Legs whose coordinate angle equals the elevation phi (1 and 4); legs 2 and 3 have theta = 180 deg - phi.
_DIRECT_LEGS = np.array([True, False, False, True])
_E_Z = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True, eq=False)
class Legs:
    """The four legs as the kinematics use them, leg by leg (mm, deg): servo axis centres ``origin_mm`` O_i (4, 3),
    ``upper_mm`` R1_i, ``lower_mm`` R0_i, ``ankle_mm`` n_i and the servo zero errors ``zero_deg`` (4,).

    The documented robot (:meth:`Geometry.legs`) has ``O_i = m u_i``, equal lengths and zero errors 0; a calibrated
    one (:class:`motion.delta4.calibration.CalibratedGeometry`) its identified values. The arm elevation of servo
    angle theta_R is ``phi_i = 45 deg - (theta_Ri + zero_i)`` and the knee ``K_i = O_i + R1_i (cos phi_i u_i +
    sin phi_i e_z)`` (reference §1.5 c, §2.1).
    """

    origin_mm: np.ndarray
    upper_mm: np.ndarray
    lower_mm: np.ndarray
    ankle_mm: np.ndarray
    zero_deg: np.ndarray

    def elevation_rad(self, servo_deg: np.ndarray) -> np.ndarray:
        """phi_i (N, 4), rad, of servo angles (N, 4), deg."""
        return np.radians(45.0 - (np.asarray(servo_deg, dtype=float) + self.zero_deg))

    def knees_mm(self, servo_deg: np.ndarray) -> np.ndarray:
        """Knee positions K_i (N, 4, 3), mm, of servo angles (N, 4), deg."""
        elevation = self.elevation_rad(servo_deg)[..., None]
        return self.origin_mm + self.upper_mm[:, None] * (np.cos(elevation) * LEG_OUTWARD + np.sin(elevation) * _E_Z)

    def ankles_mm(self, points_mm: np.ndarray) -> np.ndarray:
        """Ankle positions A_i = p + n_i u_i (N, 4, 3) of end-effector centres (N, 3)."""
        return ankle_positions(points_mm, self.ankle_mm)


def ankle_positions(points_mm: np.ndarray, ankle_mm: np.ndarray) -> np.ndarray:
    """Ankle positions A_i = p + n_i u_i (N, 4, 3) of end-effector centres p (N, 3), with ankle offsets n_i (4,)
    for every row or (N, 4) one set per row (a calibration's candidate geometries solved in one batch)."""
    return np.asarray(points_mm, dtype=float)[:, None, :] + np.asarray(ankle_mm)[..., None] * LEG_OUTWARD


@dataclass(frozen=True)
class Geometry:
    """Dimensions and limits of the 4-RSS delta (mm, degrees).

    Parameters
    ----------
    thigh_offset_mm
        m: base centre to each servo (thigh) axis, along x or y. Thesis 10 cm.
    ankle_offset_mm
        n: end-effector centre to each ankle, along x or y. Thesis 4.45 cm. Table 3's "100 mm cross" is not
        2n = 89 mm; every equation and listing uses n, so n is what counts.
    upper_arm_mm
        R1: servo axis to knee. Thesis 10 cm.
    lower_arm_mm
        R0: knee to ankle (parallelogram collapsed to a line). Thesis 17.9 cm. The thesis code uses
        R0^2 - n^2 = 300.607 cm^2 instead of 300.6075; :data:`THESIS` reproduces that.
    servo_limits_deg
        Hard servo-angle range. The document gives four sets: 0-180 (domain of the angle transforms,
        §4.3.2 d), 30-170 (calibrated with the Perspex tool, §8.1.1, and the MATLAB prompt, §8.2.1),
        <= 160 (a VB GUI check tied to its 255/190 byte factor, with no lower bound) and 25/245 (assigned,
        never used). The physical stops are 30-170, so that is the default.
    knee_limits_deg
        Allowed knee angle kappa between upper arm and projected lower leg: 0 is folded, 180 fully extended
        (both singular, §2.4). (20, 160) is the reference's default margin; (0, 180) turns the check off.
    """

    thigh_offset_mm: float = 100.0
    ankle_offset_mm: float = 44.5
    upper_arm_mm: float = 100.0
    lower_arm_mm: float = 179.0
    servo_limits_deg: tuple[float, float] = (30.0, 170.0)
    knee_limits_deg: tuple[float, float] = (20.0, 160.0)

    def __post_init__(self) -> None:
        for name in ("thigh_offset_mm", "ankle_offset_mm", "upper_arm_mm", "lower_arm_mm"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise MotionInputError(f"Geometry.{name} = {value!r}, expected a finite length > 0 mm")
        for name in ("servo_limits_deg", "knee_limits_deg"):
            low, high = getattr(self, name)
            if not (math.isfinite(low) and math.isfinite(high) and low < high):
                raise MotionInputError(f"Geometry.{name} = {(low, high)!r}, expected finite (low, high), low < high")

    @property
    def sphere_constant_mm2(self) -> float:
        """K0 = R0^2 - n^2 (mm^2): the constant of the thesis sphere equations (300.607 cm^2 as printed)."""
        return self.lower_arm_mm**2 - self.ankle_offset_mm**2

    def legs(self) -> Legs:
        """The documented legs: every servo axis at ``m u_i``, the lengths of this geometry, no zero error."""
        return Legs(
            self.thigh_offset_mm * LEG_OUTWARD,
            np.full(4, self.upper_arm_mm),
            np.full(4, self.lower_arm_mm),
            np.full(4, self.ankle_offset_mm),
            np.zeros(4),
        )

    def settings(self) -> dict[str, float | tuple[float, float]]:
        """The geometry as a plain dict, to store with a run."""
        return {
            "thigh_offset_mm": self.thigh_offset_mm,
            "ankle_offset_mm": self.ankle_offset_mm,
            "upper_arm_mm": self.upper_arm_mm,
            "lower_arm_mm": self.lower_arm_mm,
            "servo_limits_deg": self.servo_limits_deg,
            "knee_limits_deg": self.knee_limits_deg,
        }


#: Table 3 dimensions, R0 = 179 mm exactly.
NOMINAL = Geometry()
#: The constants of the thesis code: R0^2 - n^2 = 300.607 cm^2 = 30 060.7 mm^2. Reproduces every printed
#: 4th decimal of the golden vectors; NOMINAL differs from it by <= 1e-4 deg and 2e-4 mm.
THESIS = Geometry(lower_arm_mm=math.sqrt(30060.7 + 44.5**2))


def servo_from_coord_deg(coord_deg: np.ndarray) -> np.ndarray:
    """Servo angle theta_R from the coordinate angle theta, shape (N, 4), degrees.

    Notes
    -----
    Thesis §4.3.2 d, g: legs 1 and 4, theta_R = (405 - theta) mod 360; legs 2 and 3, theta_R = theta - 135.
    Equivalently theta_R = 45 deg - phi, phi being the arm elevation above the outward horizontal. The result
    is wrapped to [-135, 225) so that all four legs agree with that unified form; the thesis domain
    0-180 deg is unaffected.
    """
    coord = np.asarray(coord_deg, dtype=float)
    servo = np.where(_DIRECT_LEGS, 405.0 - coord, coord - 135.0)
    return np.mod(servo + 135.0, 360.0) - 135.0


def coord_from_servo_deg(servo_deg: np.ndarray) -> np.ndarray:
    """Coordinate angle theta in [0, 360) from the servo angle theta_R, shape (N, 4), degrees.

    Examples
    --------
    Thesis §4.3.2 d: theta_R1 = 0, 90, 180 give theta_1 = 45, 315, 225.

    >>> coord_from_servo_deg(np.array([[0.0, 90.0, 90.0, 180.0]])).tolist()
    [[45.0, 225.0, 225.0, 225.0]]
    """
    servo = np.asarray(servo_deg, dtype=float)
    return np.mod(np.where(_DIRECT_LEGS, 405.0 - servo, servo + 135.0), 360.0)


def knees_mm(servo_deg: np.ndarray, geometry: Geometry = NOMINAL) -> np.ndarray:
    """Knee positions K_i (N, 4, 3) mm from servo angles (N, 4) deg.

    Notes
    -----
    K_i = (m + R1 cos phi_i) u_i + R1 sin phi_i e_z with phi_i = 45 deg - theta_Ri (reference §1.5 c, §2.1).
    """
    return geometry.legs().knees_mm(servo_deg)
