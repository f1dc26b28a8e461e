"""Know where the robot is: a relative instrument is registered at home, then verified at a check pose.

The optical mice measure displacement only. Their frame is *registered*: the reading at the moment they are zeroed
is declared to be the home pose. That is right only to the robot's repeatability at home (the true pose of an
arrival differs from arrival to arrival: passive-joint play, backlash), and grossly wrong when the robot is not at
home (a resume registered at P4 read every row 37.5 mm off, issue 15) or a mouse is swapped, lifted or mis-wired.
So every start and every resume of a run (:func:`register_at_home`, called by :func:`bench.rigs.builder.build_rig`):

1. homes the robot from wherever the controller says it is (:func:`home_before_registering`), and zeroes the mice;
2. makes :data:`CHECK_RETURNS` excursions home -> check pose -> home. The check pose is home +
   :data:`CHECK_OFFSET_MM` (distinct sizes on the three axes, so a swapped or mirrored axis reads >= 8 mm wrong;
   pre-flighted by the controller's inverse kinematics like every move);
3. refuses to continue (:class:`RegistrationError`) when a reading at the check pose or at a return home, in the
   frame as zeroed, differs from the commanded pose by more than the tolerance, before any sample is stored (a
   frame zeroed away from home reads every pose off by the same vector, the returns home included);
4. re-references the frame to the mean of the returns home (every return approaches from the check pose, one
   direction, so the backlash is the same at every registration; the first arrival, from wherever the robot stood,
   then no longer matters).

Rule of the tolerance (per reading, 3-D distance; a reading minus its commanded pose is the difference of two
arrivals, the zeroing one and this one, plus two readings' quantisation):

.. math::

    T = k_T \\sqrt{2 \\sigma_R^2 + u_{inst}^2}, \\qquad \\sigma_R = RP_{rated} / 2.606,
    \\qquad u_{inst} = \\sqrt{2} \\cdot r / \\sqrt{12}

with :math:`r` the mice's resolution (one count), and :math:`k_T = 4.6` (the 99.99 %
quantile of the chi distribution with 3 degrees of freedom: a robot within its rated repeatability is refused
once in 10^4 checks). :math:`\\sigma_R` is the largest per-axis standard deviation consistent with the rated pose
repeatability RP = l̄ + 3 S_l (ISO 9283 7.2.2): the spread all along one axis (half-normal distances,
l̄ + 3 S_l = (√(2/π) + 3 √(1 - 2/π)) σ = 2.606 σ); an isotropic spread gives 3.616 σ, so this is the
conservative reading of a datasheet value.

Registration standard uncertainty per axis (the frame's offset from the robot's mean home, recorded with the run),
measured in the run from the n returns home, never borrowed from a document:

.. math::

    u_{reg} = \\sqrt{\\Big(\\frac{t_{p,\\nu}}{2}\\Big)^2 \\frac{s_A^2}{n} + \\frac{r^2}{6 n}}, \\qquad \\nu = 3 (n - 1)

where :math:`s_A` is the type A standard deviation of the returns pooled over the three axes and :math:`r^2/6` one
reading's quantisation (a difference of two counts, seen even when every return reads the same count). With so few
degrees of freedom a k = 2 interval on :math:`s_A/\\sqrt{n}` would cover too rarely, so the Type A term is stated at
Student's :math:`t_{p,\\nu}` for the coverage p of k = 2 (95.45 %; 3.31 at ν = 3), divided by 2: a U = 2 u that
enters the AP budget as a Type B term then keeps its coverage. (It was floored by the documents' worst rated RP,
2.7 mm, which made every mice AP read ± 1.5 mm whatever the robot did, issue 32.) Two registrations of one run (a
resume) share a frame only within :math:`\\sqrt{u_1^2 + u_2^2}` per axis.

What a relative instrument cannot see: a controller that does not know its own position (steps lost, a counter
reset while the robot stood elsewhere) moves the robot and the mice alike, so the check agrees. That needs an
absolute reference (home switches) on the controller.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from datetime import UTC, datetime
from typing import Any

import numpy as np

from bench.errors import BenchError
from bench.metrology.uncertainty import coverage_factor, resolution_uncertainty

__all__ = [
    "CHECK_OFFSET_MM",
    "CHECK_RETURNS",
    "PKM5_RATED_RP_MM",
    "RegistrationError",
    "axis_sigma_from_rp_mm",
    "check_tolerance_mm",
    "home_before_registering",
    "register_at_home",
    "registration_uncertainty_mm",
]

_log = logging.getLogger(__name__)

#: The check pose relative to home (x, y, z), mm: distinct sizes per axis, reachable from home (every leg extends).
CHECK_OFFSET_MM = (10.0, 6.0, 14.0)
#: Excursions home -> check pose -> home after the mice are zeroed.
CHECK_RETURNS = 2
#: The pkm5's pose repeatability RP as rated: the largest the documents measured (pkm5.md §6.8: RP 1.6-2.7 mm).
PKM5_RATED_RP_MM = 2.7
#: Coverage of the check's tolerance: 99.99 % quantile of the chi distribution, 3 degrees of freedom.
CHECK_COVERAGE = 4.6
#: RP / sigma for distances spread along one axis (half-normal): sqrt(2/pi) + 3 sqrt(1 - 2/pi).
_RP_PER_SIGMA_ONE_AXIS = math.sqrt(2 / math.pi) + 3 * math.sqrt(1 - 2 / math.pi)
#: Real seconds the robot is given to come to rest after the controller's DONE before the mice are read.
SETTLE_S = 0.25


class RegistrationError(BenchError):
    """The instruments disagree with the robot at the check pose: the registration cannot be trusted."""


def axis_sigma_from_rp_mm(rp_mm: float) -> float:
    """Largest per-axis standard deviation consistent with a pose repeatability ``rp_mm`` (see module docstring)."""
    return rp_mm / _RP_PER_SIGMA_ONE_AXIS


def check_tolerance_mm(rated_rp_mm: float, resolution_mm: float) -> float:
    """Largest discrepancy (3-D, mm) a registration's check reading may show: T of the module docstring."""
    sigma = axis_sigma_from_rp_mm(rated_rp_mm)
    u_inst = math.sqrt(2.0) * resolution_mm / math.sqrt(12.0)
    return CHECK_COVERAGE * math.sqrt(2 * sigma**2 + u_inst**2)


def registration_uncertainty_mm(s_a_mm: float, dof: int, returns: int, resolution_mm: float) -> float:
    """Standard uncertainty per axis of the frame registered at the mean of ``returns`` returns home: u_reg of the
    module docstring, from their pooled standard deviation ``s_a_mm`` (``dof`` degrees of freedom) and one count."""
    k_t = coverage_factor(2.0, dof) / 2.0
    return math.sqrt(
        (k_t * s_a_mm) ** 2 / returns + resolution_uncertainty(resolution_mm, difference=True) ** 2 / returns
    )


def home_before_registering(controller: Any) -> None:
    """Know where the robot is before measuring: the instruments are registered at the home pose, so a robot that
    stands anywhere else (a killed run, a resumed one, a move by hand through the firmware) is first brought home,
    pre-flighted, at the rated speed. Without this a resume registers the mice at P4 as if it were home and every
    later reading is off by the distance between them."""
    from bench.robots.pkm5_kinematics import home_steps

    home = tuple(int(s) for s in home_steps())
    where = controller.position()
    if tuple(where.steps) != home:
        _log.warning(
            "pkm5 at steps %s, not at home %s: moving home before registering the instruments", where.steps, home
        )
        controller.move_steps(home)


def register_at_home(
    controller: Any,
    instrument: Any,
    *,
    speed_factor: float = 1.0,
    rated_rp_mm: float = PKM5_RATED_RP_MM,
    sleep: Callable[[float], None] = time.sleep,
) -> dict[str, Any]:
    """Verify the registration of ``instrument`` (zeroed at home, see :func:`home_before_registering`) at the check
    pose, re-reference it to the mean return home, and return the registration record stored with the run.

    Raises
    ------
    RegistrationError
        A check-pose reading off the commanded pose by more than :func:`check_tolerance_mm`; the robot is left at
        home, nothing is stored.
    """
    from bench.robots.pkm5_kinematics import home_pose, home_steps

    home = np.asarray(home_pose()[:3], dtype=float)
    check = home + np.asarray(CHECK_OFFSET_MM)
    check_pose = (*check.tolist(), *home_pose()[3:])
    home_target = tuple(int(s) for s in home_steps())
    utc = datetime.now(UTC).isoformat(timespec="microseconds")
    at_check, at_home = [], []
    for _ in range(CHECK_RETURNS):
        controller.move_to_pose(check_pose)
        sleep(SETTLE_S / speed_factor)
        at_check.append(instrument.position_mm())
        controller.move_steps(home_target)
        sleep(SETTLE_S / speed_factor)
        at_home.append(instrument.position_mm())
    steps = tuple(int(s) for s in controller.position().steps)
    discrepancies = np.asarray(at_check) - check  # in the frame as zeroed: the check of the registration
    home_discrepancies = np.asarray(at_home) - home
    resolution = float(instrument.settings()["resolution_mm"])
    tolerance = check_tolerance_mm(rated_rp_mm, resolution)
    readings = np.vstack([discrepancies, home_discrepancies])
    distances = np.linalg.norm(readings, axis=1)
    worst = float(distances.max())
    if worst > tolerance:
        d = readings[int(distances.argmax())]
        where = (
            "check pose home + " + str(CHECK_OFFSET_MM) + " mm" if distances.argmax() < len(at_check) else "return home"
        )
        raise RegistrationError(
            f"registration check: at the {where} the instruments read "
            f"({d[0]:+.2f}, {d[1]:+.2f}, {d[2]:+.2f}) mm = {worst:.2f} mm from the commanded pose, tolerance "
            f"{tolerance:.2f} mm (rated RP {rated_rp_mm:g} mm); the robot was not at home when they were zeroed, or "
            "a mouse is swapped, lifted or miscalibrated: check the mice and the robot, then run again (nothing "
            "was measured)"
        )
    shift = home_discrepancies.mean(axis=0)  # the frame moves to the mean return home
    instrument.shift_origin(shift)
    returns = home_discrepancies - shift
    dof = 3 * (CHECK_RETURNS - 1)
    s_a = float(math.sqrt(np.sum(returns**2) / dof))
    sigma_r = axis_sigma_from_rp_mm(rated_rp_mm)
    u_mm = registration_uncertainty_mm(s_a, dof, CHECK_RETURNS, resolution)
    record = {
        "utc": utc,
        "instrument": "mice",
        "controller_steps": list(steps),
        "pose_mm": [round(float(v), 4) for v in home],
        "check_pose_mm": [round(float(v), 4) for v in check],
        "returns": CHECK_RETURNS,
        "check_discrepancy_mm": [[round(float(v), 4) for v in d] for d in discrepancies],
        "home_discrepancy_mm": [[round(float(v), 4) for v in d] for d in home_discrepancies],
        "check_discrepancy_max_mm": round(worst, 4),
        "tolerance_mm": round(tolerance, 4),
        "frame_shift_mm": [round(float(v), 4) for v in shift],
        "rated_rp_mm": rated_rp_mm,
        "sigma_rated_mm": round(sigma_r, 4),
        "sigma_type_a_mm": round(s_a, 4),
        "sigma_type_a_dof": dof,
        "u_mm": round(u_mm, 4),
        "u_source": "measured: the returns home (type A, Student's t) and one count",
    }
    _log.info(
        "registration: check-pose discrepancy %.3f mm (tolerance %.2f mm), u %.3f mm per axis",
        worst,
        tolerance,
        record["u_mm"],
    )
    return record
