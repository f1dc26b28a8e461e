"""The simulated robot's structural dynamics: how the end effector arrives at a pose (stabilisation, overshoot).

A stepper-driven parallel robot moves its actuators at constant speed and stops them abruptly (MultiStepper); the
compliant structure (printed parts, parallelograms, lead-screw nuts) makes the end effector lag behind during the
move and ring about the attained pose after it. The simulators model this with one damped structural mode per pose
coordinate, driven by the commanded ramp from the previous attained pose to the new one:

.. math::

    \\ddot p + 2 \\zeta \\omega \\dot p + \\omega^2 p = \\omega^2 u(t), \\qquad
    u(\\tau) = p_0 + (p_1 - p_0) \\, \\min(\\max(\\tau / T, 0), 1)

with T the move duration and tau the time since the move began. Starting from rest, the response is closed form
(the unit-ramp response r of the mode, superposed twice):

.. math::

    r(t) = t - \\frac{2\\zeta}{\\omega} + e^{-\\zeta\\omega t}\\Big[\\frac{2\\zeta}{\\omega}\\cos\\omega_d t
           + \\frac{2\\zeta^2 - 1}{\\omega_d}\\sin\\omega_d t\\Big] \\ (t \\ge 0), \\quad
    p(\\tau) = p_0 + (p_1 - p_0)\\,\\frac{r(\\tau) - r(\\tau - T)}{T}, \\quad \\omega_d = \\omega\\sqrt{1 - \\zeta^2}.

The ramp is straight in pose space between the two attained poses; the actuators' straight line in joint space
bends it slightly, which changes the path but not the arrival that stabilisation and overshoot measure. The mode's
frequency and damping are a [choice] of the simulator (no reference document measures them); a constant-speed
arrival at velocity v rings with an amplitude near v / omega.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["StructuralMode", "trace_times"]


def trace_times(rate_hz: float, lead_s: float, hold_s: float) -> np.ndarray:
    """Sample times (s, relative to the end of the move) from ``-lead_s`` to ``hold_s`` at ``rate_hz``."""
    first = -int(round(lead_s * rate_hz))
    last = int(round(hold_s * rate_hz))
    return np.arange(first, last + 1) / float(rate_hz)


@dataclass(frozen=True)
class StructuralMode:
    """One underdamped structural mode: natural frequency ``frequency_hz`` (> 0), damping ratio in (0, 1)."""

    frequency_hz: float = 2.5
    damping_ratio: float = 0.05

    def __post_init__(self) -> None:
        if not self.frequency_hz > 0:
            raise ValueError(f"frequency_hz = {self.frequency_hz}, expected a number > 0")
        if not 0 < self.damping_ratio < 1:
            raise ValueError(f"damping_ratio = {self.damping_ratio}, expected a number in (0, 1) (underdamped)")

    @property
    def _omegas(self) -> tuple[float, float, float]:
        """(omega, zeta, omega_d): natural and damped angular frequencies, rad/s, and the damping ratio."""
        omega = 2 * np.pi * self.frequency_hz
        return omega, self.damping_ratio, omega * np.sqrt(1 - self.damping_ratio**2)

    def _unit_ramp(self, t: np.ndarray) -> np.ndarray:
        """Response r(t) to a unit-slope ramp starting at t = 0 from rest (zero before)."""
        omega, zeta, omega_d = self._omegas
        tt = np.maximum(t, 0.0)
        ringing = np.exp(-zeta * omega * tt) * (
            2 * zeta / omega * np.cos(omega_d * tt) + (2 * zeta**2 - 1) / omega_d * np.sin(omega_d * tt)
        )
        return np.where(t > 0, tt - 2 * zeta / omega + ringing, 0.0)

    def arrival(self, t_s, start, end, duration_s: float) -> np.ndarray:
        """Positions (len(t_s), P) of a move from ``start`` (P,) to ``end`` (P,) lasting ``duration_s``, sampled at
        ``t_s`` seconds after the move ended (negative: during or before the move)."""
        t = np.asarray(t_s, dtype=float)[:, None]
        start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
        if duration_s <= 0:  # a jump (SETPOS, a stop at once): the step response is the ramp's limit T -> 0
            return start + (end - start) * self._unit_step(t)
        since_start = t + duration_s
        fraction = (self._unit_ramp(since_start) - self._unit_ramp(since_start - duration_s)) / duration_s
        return start + (end - start) * fraction

    def _unit_step(self, t: np.ndarray) -> np.ndarray:
        """Response to a unit step at t = 0 from rest (zero before)."""
        omega, zeta, omega_d = self._omegas
        tt = np.maximum(t, 0.0)
        decay = np.exp(-zeta * omega * tt) * (np.cos(omega_d * tt) + zeta * omega / omega_d * np.sin(omega_d * tt))
        return np.where(t >= 0, 1.0 - decay, 0.0)
