"""motion.delta4: kinematics of the 3-DOF 4-RSS delta robot with the laser-grid sensor (pure numpy).

Source: the dissertation "Parallel robot with an integrated direct end effector sensing system" (2006-2007),
through ``shared/reference/delta4-lasergrid.md``. The document works in cm; this API works in **mm** and
**degrees**.

Public API
----------
Geometry (frozen dataclass, mm)
    ``thigh_offset_mm`` m = 100, ``ankle_offset_mm`` n = 44.5, ``upper_arm_mm`` R1 = 100,
    ``lower_arm_mm`` R0 = 179, ``servo_limits_deg`` (30, 170), ``knee_limits_deg`` (20, 160).
    ``NOMINAL`` is Table 3; ``THESIS`` uses the code's R0^2 - n^2 = 300.607 cm^2 and reproduces the printed
    digits of every golden vector.
inverse_kinematics(points_mm (N, 3), geometry) -> IKResult
    ``servo_deg`` (N, 4), ``coord_deg`` (N, 4), ``knees_mm`` (N, 4, 3), ``knee_angle_deg`` (N, 4),
    ``reachable`` (N,) bool, ``reason`` (N,) None or "<code> (leg i)", code one of out_of_reach,
    above_knee, singular, servo_limit (first failing check, first failing leg).
forward_kinematics(servo_deg (N, 4), geometry, *, method="least_squares"|"closed_form") -> FKResult
    ``pose_mm`` (N, 3), ``residual_mm`` (N,) RMS sphere residual, ``leg_residual_mm`` (N, 4),
    ``knees_mm``, ``ok``, ``reason``.
jacobian_deg_per_mm(points_mm, geometry) -> (N, 4, 3)
quantise_thesis_deg, adc_counts, servo_deg_from_counts, legacy_command_byte, vibration_envelope
    Quantisation and vibration models of the document (module ``motion.delta4.errors_model``).
workspace_volume, reachable_square_half_width_mm, workspace_samples (module ``motion.delta4.workspace``).

Frames and angle conventions
----------------------------
Base frame: origin at the base centre, servo axes in z = 0, **z up** (towards the base), so the end effector
works at z < 0. Legs 1-4 sit at +x, -y, -x, +y; the end effector only translates.

* Servo angle theta_R (what the servo is commanded to): theta_R = 45 deg - phi for every leg, phi being the
  upper-arm elevation above the *outward* horizontal. theta_R = 45: arm horizontal outward; 135: straight down.
* Coordinate angle theta in [0, 360) (the thesis' knee-angle convention, CCW from +x or +y with z up): legs 1
  and 4, theta = (405 - theta_R) mod 360; legs 2 and 3, theta = theta_R + 135.
* Servo limits: the calibrated stops 30-170 deg (thesis §8.1.1, §8.2.1) are the hard limits. The document
  also gives 0-180 (domain of the transform), "0-160" (a VB GUI check tied to its 255/190 byte factor, no
  lower bound) and 25/245 (unused variables); those are legacy or meaningless and are not limits here.
"""

from motion.delta4.geometry import NOMINAL, THESIS, Geometry, coord_from_servo_deg, knees_mm, servo_from_coord_deg
from motion.delta4.kinematics import FKResult, IKResult, forward_kinematics, inverse_kinematics, jacobian_deg_per_mm

__all__ = [
    "Geometry",
    "NOMINAL",
    "THESIS",
    "IKResult",
    "FKResult",
    "inverse_kinematics",
    "forward_kinematics",
    "jacobian_deg_per_mm",
    "coord_from_servo_deg",
    "servo_from_coord_deg",
    "knees_mm",
]
