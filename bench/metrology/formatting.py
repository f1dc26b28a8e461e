"""Numbers as a report prints them: rounded by their uncertainty, one rule for every output.

GUM (JCGM 100:2008) 7.2.6: the numerical values of an estimate and its uncertainty should not be given with an
excessive number of digits; it usually suffices to quote U to at most two significant digits, and the estimate is
then rounded to the same decimal place. This module is the one home of that rule; the HTML and PDF reports, the
demo's ``results.csv`` and the CLI's text output all call it, so the same number reads the same
everywhere.

Examples
--------
>>> format_measured(0.44051, 0.23432)
'0.44 ± 0.23'
>>> uncertainty_decimals(0.0123)
3
>>> format_value(12.3456, 0.5)
'12.35'
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Sequence
from typing import Any

__all__ = [
    "condition_text",
    "figure_decimals",
    "format_length",
    "format_measured",
    "format_pair",
    "format_uncertainty",
    "format_value",
    "natural_key",
    "pose_label",
    "reading_decimals",
    "reading_step_mm",
    "report_order",
    "uncertainty_decimals",
]

#: Significant digits of a printed uncertainty (GUM 7.2.6).
U_SIGNIFICANT_DIGITS = 2
#: What a ``value ± U`` figure says instead of ``± 0.000`` when U is 0 or not finite.
U_NOT_DETERMINED = "U not determined"
#: Decimal places used when a value has no usable uncertainty (U = 0, not finite): a length in mm to 1 µm.
FALLBACK_DECIMALS = 3


def uncertainty_decimals(uncertainty: float, *, digits: int = U_SIGNIFICANT_DIGITS) -> int:
    """Decimal places that show ``uncertainty`` to ``digits`` significant digits (negative: tens, hundreds ...).

    d = digits − 1 − floor(log10(|U|)), computed after rounding U, so 0.0996 (-> 0.100, not 0.0996) gets 2 places
    and 9.96 gets 0 (-> 10). U = 0 or not finite gives :data:`FALLBACK_DECIMALS`.
    """
    u = abs(float(uncertainty))
    if not math.isfinite(u) or u == 0.0:
        return FALLBACK_DECIMALS
    decimals = digits - 1 - math.floor(math.log10(u))
    rounded = round(u, decimals)
    if rounded > 0 and math.floor(math.log10(rounded)) > math.floor(math.log10(u)):
        decimals -= 1
    return decimals


def reading_decimals(resolution: float) -> int:
    """Decimal places the readings of an instrument of ``resolution`` carry: those of the resolution written to
    two significant digits, trailing zeros dropped (0.01 mm -> 2, 1 mm -> 0, a 2.5 mm lattice -> 1, one count of
    an 800 cpi mouse 25.4/800 = 0.03175 mm -> 0.032 -> 3). Not finite or <= 0: :data:`FALLBACK_DECIMALS`."""
    r = abs(float(resolution))
    if not math.isfinite(r) or r == 0.0:
        return FALLBACK_DECIMALS
    decimals = uncertainty_decimals(r)
    while decimals > 0 and math.isclose(round(r, decimals - 1), round(r, decimals), rel_tol=0, abs_tol=1e-12):
        decimals -= 1
    return decimals


def figure_decimals(uncertainty: float | None = None, resolution: float | None = None) -> int:
    """The one decision of how many decimals a printed figure gets (GUM 7.2.6 and the readings' resolution).

    With a usable U: the decimal place of U at two significant digits (:func:`uncertainty_decimals`); without one
    :data:`FALLBACK_DECIMALS`; never more than the readings carry when their ``resolution`` is known
    (:func:`reading_decimals`).

    >>> figure_decimals(0.0123), figure_decimals(0.0123, resolution=0.01), figure_decimals(resolution=1.0)
    (3, 2, 0)
    """
    usable = uncertainty is not None and math.isfinite(float(uncertainty)) and float(uncertainty) != 0.0
    decimals = uncertainty_decimals(float(uncertainty)) if usable and uncertainty is not None else FALLBACK_DECIMALS
    return decimals if resolution is None else min(decimals, reading_decimals(resolution))


def reading_step_mm(values: Iterable[float] | Any) -> float | None:
    """The last decimal recorded in manual readings (0.01 for a calliper read to 0.01 mm): the largest of 1, 0.1,
    ..., 0.0001 mm that every reading is a whole multiple of; None when the readings carry more decimals."""
    import numpy as np  # imported when called: this module stays light for the window and the CLI

    array = np.asarray(values, dtype=float)
    for decimals in range(5):
        scaled = array * 10**decimals
        if np.all(np.abs(scaled - np.round(scaled)) < 1e-6):
            return 10.0**-decimals
    return None


def _fixed(value: float, decimals: int) -> str:
    if not math.isfinite(value):
        return str(value)
    if decimals >= 0:
        text = f"{value:.{decimals}f}"
    else:
        scale = 10**-decimals  # whole tens, hundreds ...: half away from zero (Python's round() is half-even)
        text = f"{math.copysign(math.floor(abs(value) / scale + 0.5), value) * scale:.0f}"
    return "0" + text[2:] if text.startswith("-0") and float(text) == 0 else text


def format_value(
    value: float, uncertainty: float | None, *, signed: bool = False, resolution: float | None = None
) -> str:
    """``value`` rounded to the decimal place of ``uncertainty`` shown to two significant digits (no usable U: to
    1 µm), never finer than the readings' ``resolution`` (:func:`figure_decimals`)."""
    text = _fixed(float(value), figure_decimals(uncertainty, resolution))
    return f"+{text}" if signed and not text.startswith("-") and float(text) != 0 else text


def format_length(value: float, *, resolution: float | None = None, signed: bool = False) -> str:
    """A length without an uncertainty of its own (a mean error, a spread): to 1 µm, or to the readings'
    ``resolution`` when known (0.01 mm calliper readings -> 2 decimals)."""
    return format_value(value, None, signed=signed, resolution=resolution)


def format_uncertainty(uncertainty: float) -> str:
    """An uncertainty on its own (a budget component, an instrument floor): two significant digits (GUM 7.2.6)."""
    return _fixed(abs(float(uncertainty)), uncertainty_decimals(uncertainty))


def format_pair(value: float, uncertainty: float, *, signed: bool = False) -> tuple[str, str]:
    """``(value, U)`` as strings, U to two significant digits and the value to the same decimal place."""
    decimals = uncertainty_decimals(uncertainty)
    return format_value(value, uncertainty, signed=signed), _fixed(abs(float(uncertainty)), decimals)


def format_measured(value: float, uncertainty: float, *, signed: bool = False) -> str:
    """``"value ± U"`` rounded by :func:`format_pair` (0.44051, 0.23432 -> ``"0.44 ± 0.23"``).

    A U of 0 or not finite (RP of 2 cycles: a bootstrap over two cycles cannot spread) is no uncertainty: the value
    is printed with ``(U not determined)``, never ``± 0.000``.
    """
    u_value = float(uncertainty)
    if not math.isfinite(u_value) or u_value == 0.0:
        return f"{format_value(value, None, signed=signed)} ({U_NOT_DETERMINED})"
    shown, u = format_pair(value, uncertainty, signed=signed)
    return f"{shown} ± {u}"


def natural_key(label: str) -> tuple[Any, ...]:
    """Sort key that orders ``P2`` before ``P10`` and ``P1`` before ``P1/x+`` (digits compared as numbers)."""
    return tuple(int(part) if part.isdigit() else part for part in re.split(r"(\d+)", str(label)))


#: How a condition column reads in a label: name -> (format of the value, unit and wording).
_CONDITION_WORDS = {"velocity_pct": "{:g} % velocity", "load_kg": "{:g} kg load"}


def condition_text(conditions: Sequence[tuple[str, float]]) -> str:
    """Conditions ``(("velocity_pct", 100.0), ("load_kg", 0.5))`` as words: ``"100 % velocity, 0.5 kg load"``."""
    words = []
    for name, value in conditions:
        template = _CONDITION_WORDS.get(name)
        words.append(template.format(value) if template else f"{name} {value:g}")
    return ", ".join(words)


def pose_label(pose: str, conditions: Sequence[tuple[str, float]] = ()) -> str:
    """A pose and its conditions as a reader reads them: ``"P1, 100 % velocity"`` (not ``P1 (velocity_pct=100)``)."""
    text = condition_text(conditions)
    return f"{pose}, {text}" if text else str(pose)


def report_order(poses: Iterable[Any]) -> tuple[Any, ...]:
    """Pose results (anything with ``.pose`` and ``.conditions``) as every output lists them: by set of conditions
    in the order the run tested them (100, 50, 10 % velocity), then by pose name in natural order (P1, P2, ...,
    P5; not the cycle order P1, P5, P4, ...)."""
    poses = list(poses)
    first_seen = {c: i for i, c in reversed(list(enumerate(p.conditions for p in poses)))}
    return tuple(sorted(poses, key=lambda p: (first_seen[p.conditions], natural_key(p.pose))))
