"""Orientation AP/RP of one command pose from calliper tilt readings, with their own GUM budget.

The pkm5's alpha and beta poses are read by a digital calliper (000 §8.2.2, §8.6.3): two depths h1, h2 through two
holes of a measuring bracket ``s`` apart, over a mirror on the end effector; the tilt is the gradient
θ = atan2(h2 − h1, s) (``sensors.md`` §6.3, reconstructed: the dissertation names "the gradient formula" and does
not give the spacing). The mice see position only, so these readings are the only orientation measurement.

Characteristics (ISO 9283:1998 7.2.1, 7.2.2; ``iso9283.md`` §6.1, §6.2):

- AP_a = ā − a_c (signed; likewise b), ā the mean of the n readings;
- RP_a = ±3 S_a, S_a = √(Σ (a_j − ā)² / (n − 1)).

Budget (GUM, JCGM 100:2008; templates ``iso9283.md`` §8.2(c), (d)):

- one depth reading: u(h)² = (δ/√12)² + (MPE/√3)² (resolution δ, maximum permissible error, rectangular);
- the tilt: u(θ)² = [s/(s² + Δh²)]²·2u(h)² + [Δh/(s² + Δh²)]²·u(s)², with Δh = s·tan θ, i.e.
  u(θ)² = [cos²θ/s]²·2u(h)² + [sinθ·cosθ/s]²·u(s)² (radians);
- the play-bias correction (the dissertation's −4° about y): a_j = reading_j − bias, with its own standard
  uncertainty u_bias (``sensors.md`` §6.3: measured at home with the actuators locked, not assumed);
- U(AP_a) = k·√(S_a²/n + u(θ̄)² + u_bias²): the calliper terms are kept whole, not divided by n, since its
  MPE and the hole spacing are systematic over a run (the conservative choice);
- U(RP_a) = k·3·S_a/√(2(n − 1)), the standard uncertainty of a sample standard deviation of n normal readings
  (u(S) ≈ S/√(2(n − 1)), ISO/IEC Guide 98-3 E.4.3 / Table E.1). The calliper's reading scatter is part of S_a and is
  not subtracted (``iso9283.md`` §8.3).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from bench.errors import ConfigError
from bench.metrology._validation import as_series
from bench.metrology.iso9283 import orientation_accuracy, orientation_repeatability
from bench.metrology.uncertainty import combine, rectangular, resolution_uncertainty

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = [
    "OrientationFigures",
    "TiltGauge",
    "orientation_figures",
    "tilt_gradient_uncertainty_deg",
    "tilt_standard_uncertainty_deg",
]


@dataclass(frozen=True)
class TiltGauge:
    """How a tilt is derived from the calliper: the bracket's hole spacing and the calliper's figures (mm, deg).

    The defaults are the worked example of ``iso9283.md`` §8.2(d) (the dissertation gives neither the spacing nor
    the calliper's data sheet): s = 40 mm ± 0.1 mm hole-position tolerance (u(s) = 0.058 mm), resolution 0.01 mm,
    MPE ± 0.02 mm; no bias correction. A lab replaces them with its bracket's and calliper's own values.
    """

    spacing_mm: float = 40.0
    u_spacing_mm: float = 0.1 / math.sqrt(3.0)
    resolution_mm: float = 0.01
    mpe_mm: float = 0.02
    u_bias_deg: float = 0.0
    bias_deg: float = 0.0  #: the measured play bias, subtracted from every reading (000 §8.6.3: -4° about y)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.spacing_mm) and self.spacing_mm > 0):
            raise ConfigError(f"hole spacing = {self.spacing_mm!r} mm, expected a positive number")
        if not math.isfinite(self.bias_deg):
            raise ConfigError(f"bias_deg = {self.bias_deg!r}, expected a finite angle in degrees")
        for name in ("u_spacing_mm", "resolution_mm", "mpe_mm", "u_bias_deg"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ConfigError(f"{name} = {value!r}, expected a finite number >= 0")

    @property
    def u_depth_mm(self) -> float:
        """u(h) of one depth reading: resolution δ/√12 and MPE/√3 combined (``iso9283.md`` §8.2(c))."""
        return combine(resolution_uncertainty(self.resolution_mm), rectangular(self.mpe_mm))

    def as_dict(self) -> dict[str, float]:
        return {
            "spacing_mm": self.spacing_mm,
            "u_spacing_mm": self.u_spacing_mm,
            "resolution_mm": self.resolution_mm,
            "mpe_mm": self.mpe_mm,
            "bias_deg": self.bias_deg,
            "u_bias_deg": self.u_bias_deg,
            "u_depth_mm": self.u_depth_mm,
        }


def tilt_gradient_uncertainty_deg(
    delta_h_mm: float, spacing_mm: float, u_depth_mm: float, u_spacing_mm: float
) -> float:
    """u(θ) of θ = atan2(Δh, s) from two independent depth readings (``iso9283.md`` §8.2(d)).

    .. math:: u^2(\\theta) = \\Big[\\frac{s}{s^2+\\Delta h^2}\\Big]^2 2u^2(h)
              + \\Big[\\frac{\\Delta h}{s^2+\\Delta h^2}\\Big]^2 u^2(s)

    Worked example there: s = 40 mm, u(h) = 0.0119 mm, u(s) = 0.058 mm give 0.024° at 0° and 0.034° at 20°.
    """
    denominator = spacing_mm * spacing_mm + delta_h_mm * delta_h_mm
    return math.degrees(
        math.hypot(spacing_mm / denominator * math.sqrt(2.0) * u_depth_mm, delta_h_mm / denominator * u_spacing_mm)
    )


def tilt_standard_uncertainty_deg(tilt_deg: float, gauge: TiltGauge) -> float:
    """u(θ) of one tilt of ``tilt_deg`` read with ``gauge``: :func:`tilt_gradient_uncertainty_deg` at the depth
    difference Δh = s·tan θ that gives it, i.e. u²(θ) = [cos²θ/s]²·2u²(h) + [sinθ·cosθ/s]²·u²(s)."""
    delta_h = gauge.spacing_mm * math.tan(math.radians(float(tilt_deg)))
    return tilt_gradient_uncertainty_deg(delta_h, gauge.spacing_mm, gauge.u_depth_mm, gauge.u_spacing_mm)


@dataclass(frozen=True)
class OrientationFigures:
    """AP and RP of one angle at one command pose, with U and the budget behind them (deg)."""

    angle: str  #: "a" or "b" (or "c")
    n: int
    commanded_deg: float
    mean_deg: float
    ap_deg: float  #: AP_a = ā − a_c, signed
    rp_deg: float  #: RP_a = 3 S_a
    u_ap_deg: float  #: expanded U(AP_a) = k · u_c
    u_rp_deg: float  #: expanded U(RP_a)
    k: float
    budget: tuple[tuple[str, float], ...]  #: (component, standard uncertainty in deg) of AP_a

    def as_json(self) -> dict[str, Any]:
        name = self.angle
        return {
            "n": self.n,
            f"cmd_{name}_deg": self.commanded_deg,
            f"mean_{name}_deg": self.mean_deg,
            f"AP_{name}_deg": self.ap_deg,
            f"U_AP_{name}_deg": self.u_ap_deg,
            f"RP_{name}_deg": self.rp_deg,
            f"U_RP_{name}_deg": self.u_rp_deg,
            "k": self.k,
            "budget_deg": dict(self.budget),
        }


def orientation_figures(
    attained_deg: ArrayLike, commanded_deg: float, gauge: TiltGauge, *, angle: str = "a", k: float = 2.0
) -> OrientationFigures:
    """AP_a, RP_a and their expanded uncertainties from n >= 2 tilt readings of one angle (module docstring).

    Raises
    ------
    InsufficientData
        With fewer than 2 readings.
    """
    readings = as_series(f"{angle}_deg readings", attained_deg, min_count=2) - gauge.bias_deg
    if not (math.isfinite(commanded_deg)):
        raise ConfigError(f"cmd_{angle}_deg = {commanded_deg!r}, expected a finite angle in degrees")
    column = readings.reshape(-1, 1)
    accuracy = orientation_accuracy(column, [commanded_deg])
    rp = orientation_repeatability(column).rp_deg[0]
    n = len(readings)
    s = rp / 3.0
    mean = accuracy.mean_deg[0]
    budget = (
        ("scatter of the mean S/√n", s / math.sqrt(n)),
        (
            "calliper tilt (resolution, MPE, hole spacing)",
            tilt_standard_uncertainty_deg(mean + gauge.bias_deg, gauge),
        ),  # at the angle the calliper read
        ("play-bias correction", gauge.u_bias_deg),
    )
    u_ap = combine(*(u for _, u in budget))
    u_rp = 3.0 * s / math.sqrt(2.0 * (n - 1))
    return OrientationFigures(
        angle=angle,
        n=n,
        commanded_deg=float(commanded_deg),
        mean_deg=float(mean),
        ap_deg=float(accuracy.ap_deg[0]),
        rp_deg=float(rp),
        u_ap_deg=float(k * u_ap),
        u_rp_deg=float(k * u_rp),
        k=float(k),
        budget=budget,
    )
