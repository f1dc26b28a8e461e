"""The paper's test trajectory for the 3-PRUS: cubic position profile and sinusoidal angles (Section 5.4,
Eqs. 36-39), with the constants reconstructed in reference ``prus3.md`` §8.

Positions are unit-less in the paper and sized like mm; angles are rad in the paper and deg here. The
trajectory frame relative to {O2} is not given: ``origin_mm`` places it (stand-in (400, -740, -700) mm,
reference §8.6). The garbled Table 3 fragments contradict the stated boundary conditions (erratum E16) and
are not used.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from motion.errors import MotionInputError

__all__ = ["Trajectory", "STAND_IN_ORIGIN_MM", "paper_trajectory"]

#: Stand-in offset of the trajectory frame in {O2} (reference §8.6), mm.
STAND_IN_ORIGIN_MM = (400.0, -740.0, -700.0)


@dataclass(frozen=True)
class Trajectory:
    """Sampled trajectory.

    Attributes
    ----------
    t_s : (N,) time, s
    pose : (N, 6) x, y, z (mm) and alpha, beta, gamma (deg)
    rate : (N, 6) time derivatives, mm/s and deg/s
    """

    t_s: np.ndarray
    pose: np.ndarray
    rate: np.ndarray


def paper_trajectory(
    t_s: ArrayLike | None = None,
    *,
    duration_s: float = 10.0,
    start_mm: tuple[float, float, float] = (40.0, 580.0, 360.0),
    end_mm: tuple[float, float, float] = (-60.0, 480.0, 640.0),
    amplitudes_rad: tuple[float, float, float] = (0.5 / math.sin(0.4 * math.pi), math.pi / 6, math.pi / 4),
    harmonics: tuple[float, float, float] = (4.0, 3.0, 6.0),
    origin_mm: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> Trajectory:
    """Poses of the paper's test trajectory.

    Parameters
    ----------
    t_s : array_like (N,), optional
        Times in [0, duration_s]; default every 0.1 s (the paper's sampling, 101 samples for 10 s).
    duration_s
        T_d; not stated in the paper, P(10) implies 10 s.
    start_mm, end_mm
        P(0) and P(T_d); end velocities are zero.
    amplitudes_rad, harmonics
        (a1, a2, a3) and (n1, n2, n3) of alpha, beta, gamma = a_k sin(n_k pi t / T_d). Only n/T_d is
        identifiable; a1 = 0.5/sin(0.4 pi) makes alpha(1 s) = 0.5 rad exactly (alternative: pi/6).
    origin_mm
        Position of the trajectory frame in {O2} (same axes).

    Notes
    -----
    .. math::

        P(t) = P_0 + 3 \\Delta (t/T)^2 - 2 \\Delta (t/T)^3, \\qquad \\Delta = P(T) - P(0)

    Examples
    --------
    The angles stated in the paper at t = 1 s: (0.5, 0.4236, 0.747) rad.

    >>> np.radians(paper_trajectory([1.0]).pose[0, 3:]).round(4).tolist()
    [0.5, 0.4236, 0.747]
    """
    times = np.arange(0.0, duration_s + 1e-9, 0.1) if t_s is None else np.atleast_1d(np.asarray(t_s, dtype=float))
    if duration_s <= 0 or times.ndim != 1 or not np.all(np.isfinite(times)):
        raise MotionInputError(f"t_s = {t_s!r}, duration_s = {duration_s!r}: expected finite times (N,) and T_d > 0")
    tau = (times / duration_s)[:, None]
    delta = np.asarray(end_mm, dtype=float) - np.asarray(start_mm, dtype=float)
    position = (
        np.asarray(start_mm, dtype=float) + np.asarray(origin_mm, dtype=float) + delta * (3 * tau**2 - 2 * tau**3)
    )
    velocity = delta * (6 * tau - 6 * tau**2) / duration_s
    omega = np.pi * np.asarray(harmonics, dtype=float) / duration_s
    amplitude = np.asarray(amplitudes_rad, dtype=float)
    angles = amplitude * np.sin(omega * times[:, None])
    angle_rates = amplitude * omega * np.cos(omega * times[:, None])
    return Trajectory(
        t_s=times,
        pose=np.concatenate([position, np.degrees(angles)], axis=1),
        rate=np.concatenate([velocity, np.degrees(angle_rates)], axis=1),
    )
