"""Angle-sensing and vibration error models of the delta-4 document: quantisation rules, ADC and command
byte mappings, and the PWM vibration simulation. Reference: ``delta4-lasergrid.md`` §3 (TV6, TV7) and §5.8.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from motion.delta4.geometry import NOMINAL, Geometry, coord_from_servo_deg, servo_from_coord_deg
from motion.delta4.kinematics import forward_kinematics, inverse_kinematics
from motion.errors import MotionInputError
from motion.sampling import as_rows

__all__ = [
    "THESIS_QUANTUM_DEG",
    "quantise_thesis_deg",
    "adc_counts",
    "servo_deg_from_counts",
    "legacy_command_byte",
    "VibrationResult",
    "vibration_envelope",
]

#: Half of the "0.55 deg" ADC step (140 deg / 255 counts), the thesis' worst-case quantisation error (§8.2.1).
THESIS_QUANTUM_DEG = 0.275
_ADC_FULL_SCALE = 255
_LEGACY_FACTOR = float(np.float32(255.0 / 190.0))  # VB Single-precision factor


def quantise_thesis_deg(servo_deg: ArrayLike, step_deg: float = THESIS_QUANTUM_DEG) -> np.ndarray:
    """The thesis' quantisation rule theta_q = floor(theta_R / step) * step, deg (same shape as the input).

    This is the modelling rule of thesis §8.2.1 (reference TV7), not the ADC transfer function
    (:func:`adc_counts`).

    Examples
    --------
    TV7: the TV1 angles become the printed TV2 input.

    >>> quantise_thesis_deg([129.3, 126.6058, 73.7283, 78.5895]).round(4).tolist()
    [129.25, 126.5, 73.7, 78.375]
    """
    if not step_deg > 0:
        raise MotionInputError(f"step_deg = {step_deg!r}, expected a step > 0 deg")
    return np.floor(np.asarray(servo_deg, dtype=float) / step_deg) * step_deg


def _check_direction(direction: int) -> None:
    if direction not in (1, -1):
        raise MotionInputError(f"direction = {direction!r}, expected +1 (count 0 at the low stop) or -1")


def adc_counts(
    servo_deg: ArrayLike, *, stops_deg: tuple[float, float] = (30.0, 170.0), direction: int = 1
) -> np.ndarray:
    """8-bit pot ADC counts for servo angles, in ``calibrated`` mode (reference §5.8 b).

    count = round(255 / (high - low) * (theta_R - low)) for direction +1, or with (high - theta_R) for -1 (the
    literal reading of thesis §5.4, count 255 at the 30 deg stop); clamped to 0..255. Integer array.
    """
    _check_direction(direction)
    low, high = stops_deg
    servo = np.asarray(servo_deg, dtype=float)
    travel = servo - low if direction == 1 else high - servo
    counts = np.floor(_ADC_FULL_SCALE / (high - low) * travel + 0.5)
    return np.clip(counts, 0, _ADC_FULL_SCALE).astype(int)


def servo_deg_from_counts(
    counts: ArrayLike, *, stops_deg: tuple[float, float] = (30.0, 170.0), direction: int = 1
) -> np.ndarray:
    """Servo angle (deg) at the centre of each ADC count: the inverse of :func:`adc_counts`."""
    _check_direction(direction)
    low, high = stops_deg
    travel = np.asarray(counts, dtype=float) * (high - low) / _ADC_FULL_SCALE
    return low + travel if direction == 1 else high - travel


def legacy_command_byte(servo_deg: ArrayLike) -> np.ndarray:
    """Command byte of the legacy VB client: round-half-up(theta_R * 255/190), integer array.

    The VB code accepts theta_R <= 160 deg only (and never checked a lower bound); here angles outside
    [30, 160] deg are refused, as the reference's ``legacy_vb`` driver mode prescribes (§5.8 a).

    Examples
    --------
    >>> legacy_command_byte([30.0, 160.0]).tolist()
    [40, 215]
    """
    servo = np.asarray(servo_deg, dtype=float)
    bad = (servo < 30.0) | (servo > 160.0) | ~np.isfinite(servo)
    if bad.any():
        raise MotionInputError(
            f"servo_deg = {float(servo[bad].ravel()[0])!r}, expected 30 <= angle <= 160 deg (legacy byte)"
        )
    return np.floor(servo * _LEGACY_FACTOR + 0.5).astype(int)


@dataclass(frozen=True)
class VibrationResult:
    """End-effector excursion under a sinusoidal angle disturbance.

    Attributes
    ----------
    t_s : (S,) sample times, s
    pose_mm : (N, S, 3) end-effector centre at each sample, mm
    min_mm, max_mm, span_mm : (N, 3) per-axis extremes and max - min, mm
    """

    t_s: np.ndarray
    pose_mm: np.ndarray
    min_mm: np.ndarray
    max_mm: np.ndarray
    span_mm: np.ndarray


def vibration_envelope(
    points_mm: ArrayLike,
    geometry: Geometry = NOMINAL,
    *,
    amplitude_deg: float = 1.0,
    frequency_hz: float = 500.0,
    phase_deg: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0),
    periods: float = 2.0,
    samples: int = 100,
    angle: str = "coordinate",
) -> VibrationResult:
    """Thesis vibration model (§7.1.3, §8.2.2, Appendix F ``Vibration``; reference TV6).

    IK of each point, then a sin(2 pi f t + delta_i) added to every leg's angle, then the closed-form FK, at
    ``samples`` times t_k = k * periods / (f (samples - 1)).

    Parameters
    ----------
    angle : {"coordinate", "servo"}
        ``"coordinate"`` perturbs the coordinate angles theta (the thesis convention: because theta = phi on
        legs 1, 4 and 180 - phi on legs 2, 3, legs 1, 4 then swing opposite to legs 2, 3 and the end
        effector moves diagonally in x-y). ``"servo"`` perturbs theta_R, i.e. all servos in phase; the end
        effector then moves only in z.

    Examples
    --------
    TV6: about 5 mm peak to peak in x and y at (0, 0, -200) mm.

    >>> from motion.delta4.geometry import THESIS
    >>> vibration_envelope([0.0, 0.0, -200.0], THESIS).span_mm.round(6).tolist()
    [[4.994811, 4.994811, 0.036735]]
    """
    if angle not in ("coordinate", "servo"):
        raise MotionInputError(f"angle = {angle!r}, expected 'coordinate' or 'servo'")
    if samples < 2 or frequency_hz <= 0:
        raise MotionInputError(f"samples = {samples!r}, frequency_hz = {frequency_hz!r}, expected >= 2 and > 0")
    points = as_rows(points_mm, 3, "points_mm")
    t_s = np.arange(samples) * periods / (frequency_hz * (samples - 1))
    wave = amplitude_deg * np.sin(2 * np.pi * frequency_hz * t_s[:, None] + np.radians(np.asarray(phase_deg)))
    servo = inverse_kinematics(points, geometry).servo_deg  # (N, 4)
    if angle == "coordinate":
        perturbed = servo_from_coord_deg(coord_from_servo_deg(servo)[:, None, :] + wave[None])
    else:
        perturbed = servo[:, None, :] + wave[None]
    fk = forward_kinematics(perturbed.reshape(-1, 4), geometry, method="closed_form")
    pose = fk.pose_mm.reshape(len(points), samples, 3)
    low, high = pose.min(axis=1), pose.max(axis=1)
    return VibrationResult(t_s=t_s, pose_mm=pose, min_mm=low, max_mm=high, span_mm=high - low)
