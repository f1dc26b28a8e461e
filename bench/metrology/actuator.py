"""Single-axis positioning: the dissertation's actuator accuracy (Groover) with the bias it hides, and ISO 230-2.

Inputs are readings of one linear actuator (or stage, or axis) at commanded targets, shape (n repeats, m
targets), in mm. Formulas from ``shared/reference/iso9283.md`` §7.1 (ISO 230-2, from memory, structure
corroborated: verify against a licensed copy) and §7.4 (dissertation Eqs. 8.1-8.3 after Groover).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from bench.errors import ConfigError
from bench.metrology._validation import as_points, as_vector, require_count

__all__ = [
    "GrooverActuator",
    "PositioningIso2302",
    "control_resolution",
    "groover_actuator",
    "positioning_iso230_2",
]


@dataclass(frozen=True)
class GrooverActuator:
    """Actuator repeatability and accuracy after Groover, plus the systematic error those figures ignore."""

    repeatability_mm: float  #: 3 σ̄, reported as ±
    accuracy_mm: float  #: CR/2 + 3 σ̄
    control_resolution_mm: float  #: CR
    sigma_mm: tuple[float, ...]  #: sample standard deviation (n - 1) per target
    mean_deviation_mm: tuple[float, ...]  #: signed x̄_i - P_i per target
    max_abs_bias_mm: float  #: max_i |x̄_i - P_i|
    n: int  #: repeats per target


@dataclass(frozen=True)
class PositioningIso2302:
    """ISO 230-2 style positioning figures of one axis (mm); bidirectional ones are None without backward data."""

    mean_deviation_forward_mm: tuple[float, ...]  #: x̄_i↑
    mean_deviation_backward_mm: tuple[float, ...] | None  #: x̄_i↓
    reversal_mm: tuple[float, ...] | None  #: B_i = x̄_i↑ - x̄_i↓
    repeatability_forward_mm: float  #: R↑ = max_i 4 s_i↑
    repeatability_backward_mm: float | None  #: R↓
    repeatability_mm: float | None  #: R = max_i max(2 s_i↑ + 2 s_i↓ + |B_i|, R_i↑, R_i↓)
    systematic_forward_mm: float  #: E↑
    systematic_backward_mm: float | None  #: E↓
    systematic_mm: float | None  #: E (bidirectional)
    mean_bidirectional_mm: float | None  #: M
    accuracy_forward_mm: float  #: A↑
    accuracy_backward_mm: float | None  #: A↓
    accuracy_mm: float | None  #: A (bidirectional)
    reversal_max_mm: float | None  #: axis B = max_i |B_i|
    n: int


def control_resolution(pitch_mm: float, steps_per_rev: int) -> float:
    """Control resolution CR = screw pitch / motor steps per revolution (dissertation Eq. 8.1), in mm/step.

    Examples
    --------
    >>> control_resolution(1.25, 200)
    0.00625

    Actuators 1-4 of the dissertation's PKM move 6.25 µm per full step.
    """
    if not (pitch_mm > 0 and steps_per_rev > 0):
        raise ConfigError(f"pitch_mm = {pitch_mm}, steps_per_rev = {steps_per_rev}, expected both > 0")
    return pitch_mm / steps_per_rev


def _targets_and_readings(targets_mm: ArrayLike, readings_mm: ArrayLike, name: str) -> tuple[np.ndarray, np.ndarray]:
    readings = as_points(name, readings_mm, dims=None)
    targets = as_vector("targets_mm", targets_mm, length=readings.shape[1])
    require_count(f"{name} repeats per target", len(readings), 2)
    return targets, readings


def groover_actuator(targets_mm: ArrayLike, readings_mm: ArrayLike, *, control_resolution_mm: float) -> GrooverActuator:
    """Actuator repeatability and accuracy by the dissertation's formulas, and the mean bias they hide.

    Dissertation Eqs. 8.2-8.3 (after Groover), with σ̄ the mean over targets of the sample standard deviation
    (n - 1) at each target (this reading reproduces Table 8-1 from Tables A.1-A.6 to ±0.01 mm):

    .. math::

        \\text{Repeatability} = \\pm 3 \\bar\\sigma, \\quad \\text{Accuracy} = CR/2 + 3 \\bar\\sigma, \\quad
        \\text{bias}_i = \\bar x_i - P_i

    Groover's accuracy assumes the mean lands on the addressable point; the signed ``mean_deviation_mm`` and
    ``max_abs_bias_mm`` report the systematic error it ignores (actuator 5 under-travels 0.13-0.16 mm).

    Parameters
    ----------
    targets_mm : array_like, shape (m,)
        Commanded travels P_i (mm).
    readings_mm : array_like, shape (n, m)
        Measured travel, one row per repeat and one column per target (mm); n >= 2.
    control_resolution_mm : float
        CR (mm/step), see `control_resolution`.

    Examples
    --------
    >>> r = groover_actuator([10, 20], [[10.0, 20.1], [10.2, 20.1]], control_resolution_mm=0.00625)
    >>> round(r.repeatability_mm, 4), tuple(round(v, 3) for v in r.mean_deviation_mm)
    (0.2121, (0.1, 0.1))

    The scatter is 0.14 mm at 10 mm and nil at 20 mm, and both targets are overshot by 0.1 mm on average.
    """
    targets, readings = _targets_and_readings(targets_mm, readings_mm, "readings_mm")
    sigma = readings.std(axis=0, ddof=1)
    bias = readings.mean(axis=0) - targets
    three_sigma = 3.0 * float(sigma.mean())
    return GrooverActuator(
        repeatability_mm=three_sigma,
        accuracy_mm=control_resolution_mm / 2.0 + three_sigma,
        control_resolution_mm=float(control_resolution_mm),
        sigma_mm=tuple(float(v) for v in sigma),
        mean_deviation_mm=tuple(float(v) for v in bias),
        max_abs_bias_mm=float(np.abs(bias).max()),
        n=len(readings),
    )


def _span(high: np.ndarray, low: np.ndarray) -> float:
    return float(high.max() - low.min())


def positioning_iso230_2(
    targets_mm: ArrayLike, forward_mm: ArrayLike, backward_mm: ArrayLike | None = None
) -> PositioningIso2302:
    """Accuracy, repeatability, systematic error and reversal of one axis in the style of ISO 230-2.

    ISO 230-2:2014 (from memory; structure corroborated by a public implementation; verify), with
    x_ij = P_ij - P_i, s the sample standard deviation (n - 1) over the n approaches (never over targets):

    .. math::

        R_i\\!\\uparrow = 4 s_i\\!\\uparrow, \\quad B_i = \\bar x_i\\!\\uparrow - \\bar x_i\\!\\downarrow, \\quad
        R_i = \\max(2 s_i\\!\\uparrow + 2 s_i\\!\\downarrow + |B_i|,\\ R_i\\!\\uparrow,\\ R_i\\!\\downarrow)

        E\\!\\uparrow = \\max_i \\bar x_i\\!\\uparrow - \\min_i \\bar x_i\\!\\uparrow, \\quad
        A\\!\\uparrow = \\max_i(\\bar x_i\\!\\uparrow + 2 s_i\\!\\uparrow) - \\min_i(\\bar x_i\\!\\uparrow - 2 s_i\\!\\uparrow)

    E, M and A combine both directions (``iso9283.md`` §7.1). By construction E >= max(E↑, E↓),
    A >= max(A↑, A↓), R >= max(R↑, R↓) and M <= E.

    Parameters
    ----------
    targets_mm : array_like, shape (m,)
        Target positions P_i (mm).
    forward_mm : array_like, shape (n, m)
        Positions measured approaching in the positive direction, one row per approach (mm).
    backward_mm : array_like, shape (n', m), optional
        Positions measured approaching in the negative direction. Without it only ↑ figures are given.
    """
    targets, forward = _targets_and_readings(targets_mm, forward_mm, "forward_mm")
    up = forward - targets
    mean_up, s_up = up.mean(axis=0), up.std(axis=0, ddof=1)
    common: dict[str, Any] = {
        "mean_deviation_forward_mm": tuple(float(v) for v in mean_up),
        "repeatability_forward_mm": float((4.0 * s_up).max()),
        "systematic_forward_mm": _span(mean_up, mean_up),
        "accuracy_forward_mm": _span(mean_up + 2 * s_up, mean_up - 2 * s_up),
        "n": len(forward),
    }
    if backward_mm is None:
        empty: dict[str, Any] = dict.fromkeys(
            (
                "mean_deviation_backward_mm",
                "reversal_mm",
                "repeatability_backward_mm",
                "repeatability_mm",
                "systematic_backward_mm",
                "systematic_mm",
                "mean_bidirectional_mm",
                "accuracy_backward_mm",
                "accuracy_mm",
                "reversal_max_mm",
            ),
        )
        return PositioningIso2302(**common, **empty)
    _, backward = _targets_and_readings(targets, backward_mm, "backward_mm")
    down = backward - targets
    mean_down, s_down = down.mean(axis=0), down.std(axis=0, ddof=1)
    reversal = mean_up - mean_down
    bidirectional_r = np.maximum.reduce([2 * s_up + 2 * s_down + np.abs(reversal), 4 * s_up, 4 * s_down])
    both_means = np.concatenate([mean_up, mean_down])
    return PositioningIso2302(
        **common,
        mean_deviation_backward_mm=tuple(float(v) for v in mean_down),
        reversal_mm=tuple(float(v) for v in reversal),
        repeatability_backward_mm=float((4.0 * s_down).max()),
        repeatability_mm=float(bidirectional_r.max()),
        systematic_backward_mm=_span(mean_down, mean_down),
        systematic_mm=_span(both_means, both_means),
        mean_bidirectional_mm=_span((mean_up + mean_down) / 2, (mean_up + mean_down) / 2),
        accuracy_backward_mm=_span(mean_down + 2 * s_down, mean_down - 2 * s_down),
        accuracy_mm=_span(
            np.concatenate([mean_up + 2 * s_up, mean_down + 2 * s_down]),
            np.concatenate([mean_up - 2 * s_up, mean_down - 2 * s_down]),
        ),
        reversal_max_mm=float(np.abs(reversal).max()),
    )
