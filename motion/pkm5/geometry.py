"""Geometry, limits and actuation data of the 5-DOF PKM 2-R(Pa-IQ)RR, R(Pa-IQ)R, as one frozen dataclass.

Every field carries its unit in its name and its source in the comment beside it. Sources are the dissertation
(``000``: 000_1cca5531533552b2.txt) and the journal paper (``001``: 001_41137034ac624704.txt); the distilled
reference is ``shared/reference/pkm5.md`` (section numbers below are that file's).

Parameters that the documents never give (leg-length offset, home stroke, motor direction, microstepping) are
calibration fields with the defaults argued in pkm5.md §2.6.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from motion.sampling import as_rows

_LEGS = 6


def _vec(*values: float) -> tuple[float, ...]:
    return tuple(float(v) for v in values)


@dataclass(frozen=True)
class Geometry:
    """Kinematic parameters of the PKM (mm, degrees).

    Frames (pkm5.md §1.3): global z up from the base centre, +x toward the leg 5-6 mount. Vectors ``oa_*`` and
    ``pd_*`` are 3-D (global and end-effector frame); ``ab_*`` and ``cd_*`` are 2-D in the pair plane: (u, w) for
    legs 1-4, (v, w') for legs 5-6. The code of 000 names the C->D bracket vectors ``DC``; here they are ``cd``.
    """

    # --- base joints A (global frame, mm): 000 App. B.1.1 OPAORG1..6
    oa_12_mm: tuple[float, ...] = _vec(-75.0, -129.9, 0.0)
    oa_34_mm: tuple[float, ...] = _vec(-75.0, 129.9, 0.0)
    oa_56_mm: tuple[float, ...] = _vec(150.0, 0.0, 60.0)
    # --- end-effector joints D (EE frame, mm): 000 App. B.1.1 PPDORG1..6
    pd_12_mm: tuple[float, ...] = _vec(-19.34, -33.50, 0.0)
    pd_34_mm: tuple[float, ...] = _vec(-19.34, 33.50, 0.0)
    pd_5_mm: tuple[float, ...] = _vec(38.69, -25.0, 0.0)
    pd_6_mm: tuple[float, ...] = _vec(38.69, 25.0, 0.0)
    # --- bracket auxiliary points E/F: D +/- this offset along the EE local z axis (000 App. B.1.1 PPDORG1top)
    bracket_half_height_mm: float = 12.0
    # --- in-plane vectors A->B (bottom pivot) and C->D (top bracket): 000 App. B.1.1 AB1..AB6, DC1..DC6
    ab_odd_mm: tuple[float, ...] = _vec(61.5, 85.0)  # legs 1, 3 (u, w)
    ab_even_mm: tuple[float, ...] = _vec(41.5, 165.0)  # legs 2, 4 (u, w)
    ab_5_mm: tuple[float, ...] = _vec(-40.0, 22.5)  # leg 5 (v, w')
    ab_6_mm: tuple[float, ...] = _vec(40.0, 22.5)  # leg 6 (v, w')
    cd_odd_mm: tuple[float, ...] = _vec(43.0, 40.0)  # legs 1, 3
    cd_even_mm: tuple[float, ...] = _vec(63.0, -40.0)  # legs 2, 4
    cd_5_mm: tuple[float, ...] = _vec(15.0, 22.5)
    cd_6_mm: tuple[float, ...] = _vec(-15.0, 22.5)

    # --- leg-length window |BC| (mm). Default: the 60 mm operating window of 000 App. B.4 (184-244 / 192-252),
    # which reproduces the dissertation's workspace; the physical stroke end is 66 mm (001 Table I: 250 / 258).
    # bench keeps the 6 mm margin by default: a pose is only "reachable" inside the window the documents validated.
    leg_min_mm: tuple[float, ...] = _vec(184, 184, 184, 184, 192, 192)
    leg_max_mm: tuple[float, ...] = _vec(244, 244, 244, 244, 252, 252)
    stroke_end_mm: tuple[float, ...] = _vec(250, 250, 250, 250, 258, 258)  # 001 Table I, hard limit
    # --- leg elevation (tilt) windows phi (deg): 000 §6.3.2, App. B.4 (strict inequalities)
    tilt_min_deg: tuple[float, ...] = _vec(34.18, 34.18, 34.18, 34.18, 56.43, 56.43)
    tilt_max_deg: tuple[float, ...] = _vec(78.73, 78.73, 78.73, 78.73, 123.57, 123.57)
    # --- orientation ranges (deg): 000 §6.3.3-6.3.4, Tables 6-2, 6-3
    alpha_range_deg: tuple[float, float] = (-35.73, 35.73)
    beta_range_deg: tuple[float, float] = (-36.8, 27.17)
    # --- alpha mode is physically consistent only on the plane x = oa_56.x - pd_5.x = 111.31 mm (pkm5.md §1.2);
    # 000 App. B.1.1 itself uses x = 111.36, hence a tolerance of 0.06 mm.
    alpha_plane_tolerance_mm: float = 0.06

    # --- actuation (000 §7.3.1, App. C.2, Eq. 8.1): M8 lead screw (1.25 mm pitch), 200 / 400 full steps per rev
    mm_per_full_step: tuple[float, ...] = _vec(0.00625, 0.00625, 0.00625, 0.00625, 0.003125, 0.003125)
    # --- calibration fields the documents never give (pkm5.md §2.6)
    microsteps: int = 1  # TB6560 S3/S4 setting; App. C.2 assumes full steps
    step_direction: tuple[int, ...] = (1, 1, 1, 1, 1, 1)  # +1: positive steps lengthen the leg
    leg_length_offset_mm: tuple[float, ...] = _vec(184, 184, 184, 184, 192, 192)  # |BC| at zero stroke (001 Table I)
    home_stroke_mm: float = 5.0  # 000 §8.3: every actuator at 5 mm stroke before a test
    max_speed_steps_per_s: float = 200.0  # 000 App. B.2 setMaxSpeed(200)

    # ----------------------------------------------------------------------------------------------------------
    def __post_init__(self) -> None:
        for name in (
            "leg_min_mm",
            "leg_max_mm",
            "stroke_end_mm",
            "tilt_min_deg",
            "tilt_max_deg",
            "mm_per_full_step",
            "step_direction",
            "leg_length_offset_mm",
        ):
            if len(getattr(self, name)) != _LEGS:
                raise ValueError(f"Geometry.{name} = {getattr(self, name)!r}, expected {_LEGS} values (one per leg)")
        if any(d not in (-1, 1) for d in self.step_direction):
            raise ValueError(f"Geometry.step_direction = {self.step_direction!r}, expected each entry +1 or -1")
        if self.microsteps < 1:
            raise ValueError(f"Geometry.microsteps = {self.microsteps!r}, expected an integer >= 1")

    def replace(self, **changes: Any) -> Geometry:
        """A copy with some fields changed (``dataclasses.replace``), validated again."""
        return dataclasses.replace(self, **changes)

    @property
    def alpha_plane_x_mm(self) -> float:
        """x of the only plane on which alpha poses are consistent: 150 - 38.69 = 111.31 mm (pkm5.md §1.2)."""
        return self.oa_56_mm[0] - self.pd_5_mm[0]

    @property
    def mm_per_step(self) -> np.ndarray:
        """Leg-length change per (micro)step, mm, shape (6,)."""
        return np.asarray(self.mm_per_full_step) / self.microsteps

    @property
    def home_lengths_mm(self) -> np.ndarray:
        """Leg lengths |BC| at the home stroke, shape (6,): (189 x4, 197 x2) with the defaults."""
        return np.asarray(self.leg_length_offset_mm) + self.home_stroke_mm

    def as_dict(self) -> dict[str, Any]:
        """Plain-data form (stored with every run)."""
        return dataclasses.asdict(self)


#: The documented robot (000 App. B.1.1 geometry, App. B.4 limits, App. C.2 actuation).
DEFAULT_GEOMETRY = Geometry()


def lengths_to_steps(lengths_mm: ArrayLike, geometry: Geometry = DEFAULT_GEOMETRY) -> np.ndarray:
    """Absolute step targets for leg lengths.

    ``steps = direction * round((L - L0) / (CR / microsteps))`` with L0 the leg-length offset (zero stroke) and CR
    the control resolution of 000 Eq. 8.1 (0.00625 mm/step for legs 1-4, 0.003125 for legs 5-6).

    Parameters
    ----------
    lengths_mm : array_like, shape (N, 6)
        Leg lengths |BC| in mm.

    Returns
    -------
    ndarray of int64, shape (N, 6)
        Steps from the zero stroke of each leg.
    """
    lengths = _as_legs(lengths_mm, "lengths_mm")
    stroke = lengths - np.asarray(geometry.leg_length_offset_mm)
    return (np.rint(stroke / geometry.mm_per_step) * np.asarray(geometry.step_direction)).astype(np.int64)


def steps_to_lengths(steps: ArrayLike, geometry: Geometry = DEFAULT_GEOMETRY) -> np.ndarray:
    """Leg lengths |BC| (mm, shape (N, 6)) for absolute step counts (shape (N, 6)); inverse of lengths_to_steps."""
    counts = _as_legs(steps, "steps")
    direction = np.asarray(geometry.step_direction)
    return np.asarray(geometry.leg_length_offset_mm) + counts * direction * geometry.mm_per_step


def _as_legs(values: ArrayLike, name: str) -> np.ndarray:
    return as_rows(values, _LEGS, name)
