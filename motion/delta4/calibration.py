"""Kinematic calibration model of the delta-4: per-leg deviations from the documented geometry, the forward model of
what a position instrument reads, and the commands that compensate an identified geometry. Pure numpy.

Per leg i (outward unit vector u_i, v_i = e_z x u_i, legs 1-4 at +x, -y, -x, +y) the calibrated leg has

* ``servo_zero_i_deg``: the servo's zero error; the arm elevation is ``phi_i = 45 deg - (theta_Ri + zero_i)``;
* ``upper_arm_i_mm``, ``lower_arm_i_mm``: R1 and R0 of that leg (added to ``Geometry.upper_arm_mm`` / ``lower_arm_mm``);
* ``radial_i_mm``, ``sideways_i_mm``, ``height_i_mm``: the servo axis centre moved from ``m u_i`` by
  ``radial u_i + sideways v_i + height e_z`` (an ankle offset on the end effector is the same column as the
  radial one with the opposite sign, so only their difference is a parameter).

Knee ``K_i = O_i + R1_i (cos phi_i u_i + sin phi_i e_z)`` with ``O_i = (m + radial_i) u_i + sideways_i v_i +
height_i e_z``, ankle ``A_i = p + n u_i``, closure ``|A_i - K_i| = R0_i``. Four legs drive three coordinates: a
robot whose legs disagree (any geometric error) stands where the four closures are best met in least squares
(equal leg compliance), the same fit as ``motion.delta4.forward_kinematics(..., method="least_squares")``. The
inverse kinematics of a calibrated leg is the closed form of the documented one (outer knee):
``a cos phi + b sin phi = c`` with ``q = A_i - O_i``, ``a = q.u_i``, ``b = q.e_z``,
``c = (|q|^2 + R1^2 - R0^2) / (2 R1)``, ``phi = atan2(b, a) + arccos(c / hypot(a, b))``.

A relative instrument (the camera spot sensor reads the plane position from its registration pose) adds its
registration ``reg_x_mm .. reg_z_mm``: a reading is ``m = p + r`` on the measured axes.

Base parameters: moving every servo axis centre by one vector t moves the attained position by t, so
``(radial_i, sideways_i, height_i) - (t.u_i, t.v_i, t_z)`` with the registration ``r + t`` reads the same. No
instrument can tell them apart: :data:`FRAME_PARAMETERS` (``radial_1``, ``radial_4``, ``height_4``: t_x, t_y, t_z)
are held at 0 and :data:`BASE_PARAMETERS` are the rest (:func:`base_equivalent` maps any deviations onto them).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from motion.delta4.geometry import LEG_OUTWARD, LEG_SIDEWAYS, NOMINAL, Geometry, Legs, ankle_positions
from motion.delta4.kinematics import forward_kinematics, inverse_kinematics
from motion.errors import MotionInputError

__all__ = [
    "BASE_PARAMETERS",
    "FRAME_PARAMETERS",
    "PARAMETERS",
    "REGISTRATION",
    "TOLERANCES",
    "UNITS",
    "CalibratedGeometry",
    "ForwardModel",
    "attained_positions",
    "base_equivalent",
    "commanded_servo_deg",
    "compensation_geometry",
    "leg_parameters",
    "prior_sigma",
]

_E_Z = np.array([0.0, 0.0, 1.0])
_KINDS = ("servo_zero", "upper_arm", "lower_arm", "radial", "sideways", "height")
_AXES = "xyz"
#: Per-leg deviations, leg by leg (``servo_zero_1_deg``, ``upper_arm_1_mm``, ... ``height_4_mm``).
PARAMETERS = tuple(f"{kind}_{leg}_{'deg' if kind == 'servo_zero' else 'mm'}" for leg in range(1, 5) for kind in _KINDS)
REGISTRATION = tuple(f"reg_{axis}_mm" for axis in _AXES)
#: The three parameters that fix the base frame against the end effector (module docstring), held at 0.
FRAME_PARAMETERS = ("radial_1_mm", "radial_4_mm", "height_4_mm")
#: The parameters an instrument can identify at best: all but the frame's.
BASE_PARAMETERS = tuple(name for name in PARAMETERS if name not in FRAME_PARAMETERS)
UNITS = {name: name.rsplit("_", 1)[1] for name in PARAMETERS + REGISTRATION}
_GAUSS_NEWTON_ITERATIONS = 8
#: Manufacturing tolerances, 1 sigma per parameter family: servo zeros 0.3 deg (a horn set on its spline and
#: trimmed by hand), arm lengths 0.3 mm and servo axis positions 0.3 mm (printed parts, hand assembly): the same
#: sizes as the pkm5's joints (:data:`motion.pkm5.calibration.TOLERANCES`). The prior of the maximum a posteriori
#: identification (``bench calibrate --fit map``) and the size of the simulator's seeded true geometry.
TOLERANCES = {"servo_zero": 0.3, "arm": 0.3, "axis": 0.3}


def tolerance(name: str) -> float:
    """The 1-sigma tolerance of deviation ``name`` about the drawing (:data:`TOLERANCES`; ``inf`` for the
    registration, which the instrument's placement sets)."""
    _check_names((name,))
    if name.startswith("reg_"):
        return float("inf")
    if name.startswith("servo_zero_"):
        return TOLERANCES["servo_zero"]
    return TOLERANCES["arm"] if name.startswith(("upper_arm_", "lower_arm_")) else TOLERANCES["axis"]


def prior_sigma(names: Iterable[str]) -> np.ndarray:
    """The 1-sigma prior of each of ``names`` (base parameters and registration) for the MAP fit.

    A base parameter's axis position is measured from the frame that legs 1 and 4 fix (module docstring): it is the
    deviation of its own axis less the frame translation t, itself drawn from the axes' tolerance, so it spreads by
    sqrt 2 times the tolerance (the shared t also correlates them, which a per-parameter prior leaves out: a slightly
    looser prior than the truth's). Servo zeros and arm lengths are not moved by t: their tolerance as it is.
    """
    sigma = []
    for name in _check_names(names):
        moved_by_frame = name.startswith(("radial_", "sideways_", "height_"))
        sigma.append(tolerance(name) * (np.sqrt(2.0) if moved_by_frame else 1.0))
    return np.array(sigma)


def _check_names(names: Iterable[str]) -> tuple[str, ...]:
    names = tuple(names)
    for name in names:
        if name not in UNITS:
            raise MotionInputError(
                f"parameter {name!r} is not a delta4 calibration parameter, expected one of "
                f"{', '.join(PARAMETERS + REGISTRATION)}"
            )
    return names


def leg_parameters(free: Iterable[str], theta: ArrayLike, nominal: Geometry = NOMINAL) -> Legs:
    """The :class:`~motion.delta4.geometry.Legs` of the geometry under deviations ``theta`` of parameters ``free``
    (registration entries are not geometry and are skipped)."""
    deviation = {kind: np.zeros(4) for kind in _KINDS}
    for slot, value in zip(_leg_slots(tuple(free)), np.asarray(theta, dtype=float)):
        if slot is not None:
            deviation[slot[0]][slot[1]] = value
    origin = (
        (nominal.thigh_offset_mm + deviation["radial"])[:, None] * LEG_OUTWARD
        + deviation["sideways"][:, None] * LEG_SIDEWAYS
        + deviation["height"][:, None] * _E_Z
    )
    return Legs(
        origin,
        nominal.upper_arm_mm + deviation["upper_arm"],
        nominal.lower_arm_mm + deviation["lower_arm"],
        np.full(4, nominal.ankle_offset_mm),
        deviation["servo_zero"],
    )


@lru_cache(maxsize=64)
def _leg_slots(free: tuple[str, ...]) -> tuple[tuple[str, int] | None, ...]:
    """Per name of ``free`` (checked): its kind and leg index, None for a registration entry. Parsed once per
    parameter set: a fit evaluates the same set hundreds of times."""
    return tuple(
        None if name.startswith("reg_") else (name.rsplit("_", 2)[0], int(name.rsplit("_", 2)[1]) - 1)
        for name in _check_names(free)
    )


def _moved_axes(full: dict[str, float], t: np.ndarray) -> dict[str, float]:
    """``full`` (every leg parameter) with every servo axis centre moved by the vector ``t`` (mm)."""
    out = dict(full)
    for leg in range(4):
        out[f"radial_{leg + 1}_mm"] = out.get(f"radial_{leg + 1}_mm", 0.0) + float(t @ LEG_OUTWARD[leg])
        out[f"sideways_{leg + 1}_mm"] = out.get(f"sideways_{leg + 1}_mm", 0.0) + float(t @ LEG_SIDEWAYS[leg])
        out[f"height_{leg + 1}_mm"] = out.get(f"height_{leg + 1}_mm", 0.0) + float(t[2])
    return out


@dataclass(frozen=True)
class CalibratedGeometry:
    """A calibrated delta4: the documented ``nominal`` with the leg deviations ``deviations`` ((name, value) pairs
    of :data:`PARAMETERS`), in the instrument's frame when made by :func:`compensation_geometry`.

    :func:`motion.delta4.inverse_kinematics` and :func:`motion.delta4.jacobian_deg_per_mm` solve it leg by leg
    (:meth:`legs`), with the nominal servo and knee limits, so the driver's IK and the pre-flight (reach, limits,
    singularity) take it wherever they take a :class:`~motion.delta4.geometry.Geometry`; :meth:`attained_mm` is its
    forward kinematics (the least-squares closure of the four legs).
    """

    deviations: tuple[tuple[str, float], ...]
    nominal: Geometry = NOMINAL

    def __post_init__(self) -> None:
        names = _check_names(name for name, _ in self.deviations)
        registration = [name for name in names if name in REGISTRATION]
        if registration:
            raise MotionInputError(
                f"CalibratedGeometry: {registration[0]} is not a leg parameter, expected the "
                "registration folded into the servo axes (compensation_geometry)"
            )

    @property
    def servo_limits_deg(self) -> tuple[float, float]:
        return self.nominal.servo_limits_deg

    @property
    def knee_limits_deg(self) -> tuple[float, float]:
        return self.nominal.knee_limits_deg

    def legs(self) -> Legs:
        names, values = zip(*self.deviations) if self.deviations else ((), ())
        return leg_parameters(names, values, self.nominal)

    def attained_mm(self, servo_deg: ArrayLike) -> np.ndarray:
        """Where this robot stands at servo angles (N, 4): :func:`attained_positions`."""
        names, values = zip(*self.deviations) if self.deviations else ((), ())
        return attained_positions(servo_deg, names, values, self.nominal)

    def settings(self) -> dict[str, Any]:
        return {**self.nominal.settings(), "deviations": {name: value for name, value in self.deviations}}


def compensation_geometry(params: Mapping[str, Any], nominal: Geometry = NOMINAL) -> CalibratedGeometry:
    """The geometry a compensated run commands by, from a stored calibration's parameters (``{"parameters": {name:
    {"value": ...}}}``, as ``bench calibrate`` stores them).

    The calibration predicts a reading ``m = p(theta) + r``; moving every servo axis centre by ``r`` moves every
    attained position by ``r`` (module docstring), so with the registration folded into the axes the geometry's
    own frame is the instrument's and its IK of a target gives the servo angles whose predicted reading is it.
    """
    try:
        entries = {name: float(entry["value"]) for name, entry in params["parameters"].items()}
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise MotionInputError(
            f"kinematic calibration parameters: {exc!r}, expected {{'parameters': {{name: {{'value': number}}}}}}}}"
        ) from None
    _check_names(entries)
    shift = np.array([entries.get(name, 0.0) for name in REGISTRATION])
    legs = _moved_axes({n: v for n, v in entries.items() if n not in REGISTRATION}, shift)
    return CalibratedGeometry(tuple((name, legs[name]) for name in PARAMETERS if name in legs), nominal)


def base_equivalent(deviations: dict[str, float]) -> dict[str, float]:
    """The deviations (every name of :data:`PARAMETERS` and :data:`REGISTRATION`, missing ones 0) expressed in the
    base parameters: the frame translation t = (radial_1, radial_4, height_4) taken off every servo axis centre
    and added to the registration (module docstring); the readings are the same."""
    _check_names(deviations)
    full = {name: float(deviations.get(name, 0.0)) for name in PARAMETERS + REGISTRATION}
    t = np.array([full["radial_1_mm"], full["radial_4_mm"], full["height_4_mm"]])
    full = _moved_axes(full, -t)
    for axis, shift in zip(_AXES, t):
        full[f"reg_{axis}_mm"] += float(shift)
    return full


def _registration(free: Sequence[str], theta: ArrayLike) -> np.ndarray:
    shift = np.zeros(3)
    for name, value in zip(free, np.asarray(theta, dtype=float)):
        if name.startswith("reg_"):
            shift[_AXES.index(name[4])] = value
    return shift


def commanded_servo_deg(
    points_mm: ArrayLike, free: Iterable[str] = (), theta: ArrayLike = (), nominal: Geometry = NOMINAL
) -> np.ndarray:
    """Servo angles (N, 4) that close every leg of the geometry under ``theta`` at positions ``points_mm`` (N, 3)
    (the IK of :func:`compensation_geometry`, module docstring; NaN rows where a leg cannot close). A registration
    in ``free`` is folded in: the points are instrument readings, so the command makes the predicted reading equal
    the target."""
    free = _check_names(free)
    params = {"parameters": {name: {"value": value} for name, value in zip(free, np.asarray(theta, dtype=float))}}
    # a CalibratedGeometry stands in for a Geometry: the IK reads only the legs, which it gives
    result = inverse_kinematics(points_mm, compensation_geometry(params, nominal))  # type: ignore[arg-type]
    closes = np.array([not str(reason).startswith("out_of_reach") for reason in result.reason])
    return np.where(closes[:, None], result.servo_deg, np.nan)


def attained_positions(
    servo_deg: ArrayLike,
    free: Iterable[str] = (),
    theta: ArrayLike = (),
    nominal: Geometry = NOMINAL,
    start_mm: ArrayLike | None = None,
) -> np.ndarray:
    """End-effector positions (N, 3) where the robot of deviations ``theta`` stands at servo angles (N, 4): the
    least-squares closure of the four legs, by Gauss-Newton from ``start_mm`` (default: the documented
    geometry's least-squares FK). Registration is not added (see :class:`ForwardModel`)."""
    free = _check_names(free)
    servo = np.atleast_2d(np.asarray(servo_deg, dtype=float))
    legs = leg_parameters(free, theta, nominal)
    p = (
        forward_kinematics(servo, nominal, method="least_squares").pose_mm
        if start_mm is None
        else np.array(start_mm, dtype=float)
    )
    return _closure(legs.knees_mm(servo), legs.ankle_mm, legs.lower_mm, p)


def _closure(knees: np.ndarray, ankle_mm: np.ndarray, lower_mm: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Positions (N, 3) where the four legs of each row close best, by Gauss-Newton from ``p`` (N, 3): knees
    (N, 4, 3), ankle offsets and lower arms (4,) for every row or (N, 4) one set per row."""
    for _ in range(_GAUSS_NEWTON_ITERATIONS):
        span = ankle_positions(p, ankle_mm) - knees  # A_i - K_i
        length = np.linalg.norm(span, axis=-1)
        residual = length - lower_mm
        jac = span / length[..., None]  # d|A_i - K_i| / dp
        normal = np.einsum("nij,nik->njk", jac, jac)
        p = p - np.linalg.solve(normal, np.einsum("nij,ni->nj", jac, residual)[..., None])[..., 0]
    return p


class ForwardModel:
    """Predicted instrument readings of the attained positions under the free parameters (the model of
    :func:`bench.metrology.kinematic_calibration.identify`).

    Parameters
    ----------
    servo_deg : array_like (N, 4)
        Commanded servo angles of each measured pose.
    free : sequence of str
        Free parameters (:data:`PARAMETERS`, :data:`REGISTRATION`).
    axes : sequence of int
        Coordinates the instrument reads (the camera spot on an x-y plane: 0, 1).
    """

    _STEP = {"deg": 1e-4, "mm": 1e-4}

    def __init__(
        self, servo_deg: ArrayLike, free: Iterable[str], axes: Sequence[int] = (0, 1), nominal: Geometry = NOMINAL
    ) -> None:
        self.servo_deg = np.atleast_2d(np.asarray(servo_deg, dtype=float))
        if self.servo_deg.shape[1:] != (4,):
            raise MotionInputError(f"servo_deg has shape {self.servo_deg.shape}, expected (N, 4)")
        self.free = _check_names(free)
        self.axes = tuple(int(a) for a in axes)
        if not self.axes or any(a not in (0, 1, 2) for a in self.axes):
            raise MotionInputError(f"axes = {axes!r}, expected a subset of (0, 1, 2) (x, y, z)")
        self.nominal = nominal
        self._start = forward_kinematics(self.servo_deg, nominal, method="least_squares").pose_mm

    @property
    def units(self) -> tuple[str, ...]:
        return tuple(UNITS[name] for name in self.free)

    @property
    def bound(self) -> np.ndarray:
        """Largest plausible |deviation|: 5 mm or 5 deg per leg parameter, 20 mm of registration."""
        return np.array([20.0 if n.startswith("reg_") else 5.0 for n in self.free])

    def predict(self, theta: ArrayLike) -> np.ndarray:
        """Readings (N, len(axes)): attained position plus registration, on the measured axes."""
        return self._predict_each([theta])[0]

    def _predict_each(self, thetas: Sequence[ArrayLike]) -> list[np.ndarray]:
        """:meth:`predict` of each of ``thetas``, the closures of all of them solved in one batch (the same
        arithmetic row by row: a Jacobian's 2 K predictions cost little more than one)."""
        legs = [leg_parameters(self.free, theta, self.nominal) for theta in thetas]
        if not legs:
            return []
        rows = len(self.servo_deg)
        p = _closure(
            np.concatenate([leg.knees_mm(self.servo_deg) for leg in legs]),
            np.repeat([leg.ankle_mm for leg in legs], rows, axis=0),
            np.repeat([leg.lower_mm for leg in legs], rows, axis=0),
            np.tile(self._start, (len(legs), 1)),
        )
        return [
            (part + _registration(self.free, theta))[:, self.axes]
            for part, theta in zip(np.split(p, len(legs)), thetas)
        ]

    def jacobian(self, theta: ArrayLike) -> np.ndarray:
        """d reading / d theta (N, len(axes), K): central differences (registration columns exact)."""
        theta = np.asarray(theta, dtype=float)
        varied = [k for k, name in enumerate(self.free) if not name.startswith("reg_")]
        steps = np.zeros((len(varied), len(theta)))
        steps[np.arange(len(varied)), varied] = [self._STEP[UNITS[self.free[k]]] for k in varied]
        readings = iter(self._predict_each([theta + sign * step for step in steps for sign in (1, -1)]))
        columns = []
        for _k, name in enumerate(self.free):
            if name.startswith("reg_"):
                column = np.zeros((len(self.servo_deg), len(self.axes)))
                if _AXES.index(name[4]) in self.axes:
                    column[:, self.axes.index(_AXES.index(name[4]))] = 1.0
            else:
                column = (next(readings) - next(readings)) / (2 * self._STEP[UNITS[name]])
            columns.append(column)
        return np.stack(columns, axis=-1)
