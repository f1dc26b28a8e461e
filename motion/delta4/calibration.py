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

import numpy as np

from motion.delta4.geometry import LEG_OUTWARD, LEG_SIDEWAYS, NOMINAL, Geometry
from motion.delta4.kinematics import forward_kinematics
from motion.errors import MotionInputError

__all__ = ["BASE_PARAMETERS", "FRAME_PARAMETERS", "PARAMETERS", "REGISTRATION", "UNITS", "ForwardModel",
           "attained_positions", "base_equivalent", "commanded_servo_deg", "leg_parameters"]

_E_Z = np.array([0.0, 0.0, 1.0])
_KINDS = ("servo_zero", "upper_arm", "lower_arm", "radial", "sideways", "height")
_AXES = "xyz"
#: Per-leg deviations, leg by leg (``servo_zero_1_deg``, ``upper_arm_1_mm``, ... ``height_4_mm``).
PARAMETERS = tuple(f"{kind}_{leg}_{'deg' if kind == 'servo_zero' else 'mm'}" for leg in range(1, 5)
                   for kind in _KINDS)
REGISTRATION = tuple(f"reg_{axis}_mm" for axis in _AXES)
#: The three parameters that fix the base frame against the end effector (module docstring), held at 0.
FRAME_PARAMETERS = ("radial_1_mm", "radial_4_mm", "height_4_mm")
#: The parameters an instrument can identify at best: all but the frame's.
BASE_PARAMETERS = tuple(name for name in PARAMETERS if name not in FRAME_PARAMETERS)
UNITS = {name: name.rsplit("_", 1)[1] for name in PARAMETERS + REGISTRATION}
_GAUSS_NEWTON_ITERATIONS = 8


def _check_names(names) -> tuple[str, ...]:
    names = tuple(names)
    for name in names:
        if name not in UNITS:
            raise MotionInputError(f"parameter {name!r} is not a delta4 calibration parameter, expected one of "
                                   f"{', '.join(PARAMETERS + REGISTRATION)}")
    return names


def leg_parameters(free, theta, nominal: Geometry = NOMINAL) -> dict[str, np.ndarray]:
    """Per-leg arrays (4,) of the geometry under deviations ``theta`` of parameters ``free``: ``zero_deg``,
    ``upper_mm``, ``lower_mm``, ``origin_mm`` (4, 3, the servo axis centres O_i) and ``ankle_mm`` (n)."""
    deviation = {kind: np.zeros(4) for kind in _KINDS}
    for name, value in zip(_check_names(free), np.asarray(theta, dtype=float)):
        if name.startswith("reg_"):
            continue
        kind, leg = name.rsplit("_", 2)[0], int(name.rsplit("_", 2)[1])
        deviation[kind][leg - 1] = value
    origin = ((nominal.thigh_offset_mm + deviation["radial"])[:, None] * LEG_OUTWARD
              + deviation["sideways"][:, None] * LEG_SIDEWAYS + deviation["height"][:, None] * _E_Z)
    return {"zero_deg": deviation["servo_zero"], "upper_mm": nominal.upper_arm_mm + deviation["upper_arm"],
            "lower_mm": nominal.lower_arm_mm + deviation["lower_arm"], "origin_mm": origin,
            "ankle_mm": np.full(4, nominal.ankle_offset_mm)}


def base_equivalent(deviations: dict[str, float]) -> dict[str, float]:
    """The deviations (every name of :data:`PARAMETERS` and :data:`REGISTRATION`, missing ones 0) expressed in the
    base parameters: the frame translation t = (radial_1, radial_4, height_4) taken off every servo axis centre
    and added to the registration (module docstring); the readings are the same."""
    _check_names(deviations)
    full = {name: float(deviations.get(name, 0.0)) for name in PARAMETERS + REGISTRATION}
    t = np.array([full["radial_1_mm"], full["radial_4_mm"], full["height_4_mm"]])
    for leg in range(4):
        full[f"radial_{leg + 1}_mm"] -= float(t @ LEG_OUTWARD[leg])
        full[f"sideways_{leg + 1}_mm"] -= float(t @ LEG_SIDEWAYS[leg])
        full[f"height_{leg + 1}_mm"] -= float(t[2])
    for axis, shift in zip(_AXES, t):
        full[f"reg_{axis}_mm"] += float(shift)
    return full


def _registration(free, theta) -> np.ndarray:
    shift = np.zeros(3)
    for name, value in zip(free, np.asarray(theta, dtype=float)):
        if name.startswith("reg_"):
            shift[_AXES.index(name[4])] = value
    return shift


def _knees(servo_deg: np.ndarray, legs: dict) -> np.ndarray:
    elevation = np.radians(45.0 - (servo_deg + legs["zero_deg"]))[..., None]  # (N, 4, 1)
    upper = legs["upper_mm"][:, None]
    return legs["origin_mm"] + upper * (np.cos(elevation) * LEG_OUTWARD + np.sin(elevation) * _E_Z)


def commanded_servo_deg(points_mm, free=(), theta=(), nominal: Geometry = NOMINAL) -> np.ndarray:
    """Servo angles (N, 4) that close every leg of the geometry under ``theta`` at positions ``points_mm`` (N, 3)
    (module docstring; NaN where a leg cannot close). A registration in ``free`` is taken off first: the points
    are instrument readings, so the command makes the predicted reading equal the target."""
    free = _check_names(free)
    points = np.atleast_2d(np.asarray(points_mm, dtype=float)) - _registration(free, theta)
    legs = leg_parameters(free, theta, nominal)
    q = points[:, None, :] + legs["ankle_mm"][:, None] * LEG_OUTWARD - legs["origin_mm"]  # (N, 4, 3)
    a, b = np.einsum("nij,ij->ni", q, LEG_OUTWARD), q[..., 2]
    upper, lower = legs["upper_mm"], legs["lower_mm"]
    c = (np.sum(q**2, axis=-1) + upper**2 - lower**2) / (2.0 * upper)
    with np.errstate(invalid="ignore"):
        elevation = np.arctan2(b, a) + np.arccos(c / np.hypot(a, b))
    servo = 45.0 - np.degrees(elevation) - legs["zero_deg"]
    return np.mod(servo + 135.0, 360.0) - 135.0


def attained_positions(servo_deg, free=(), theta=(), nominal: Geometry = NOMINAL, start_mm=None) -> np.ndarray:
    """End-effector positions (N, 3) where the robot of deviations ``theta`` stands at servo angles (N, 4): the
    least-squares closure of the four legs, by Gauss-Newton from ``start_mm`` (default: the documented
    geometry's least-squares FK). Registration is not added (see :class:`ForwardModel`)."""
    free = _check_names(free)
    servo = np.atleast_2d(np.asarray(servo_deg, dtype=float))
    legs = leg_parameters(free, theta, nominal)
    knees = _knees(servo, legs)
    p = (forward_kinematics(servo, nominal, method="least_squares").pose_mm if start_mm is None
         else np.array(start_mm, dtype=float))
    for _ in range(_GAUSS_NEWTON_ITERATIONS):
        span = p[:, None, :] + legs["ankle_mm"][:, None] * LEG_OUTWARD - knees  # A_i - K_i
        length = np.linalg.norm(span, axis=-1)
        residual = length - legs["lower_mm"]
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

    def __init__(self, servo_deg, free, axes=(0, 1), nominal: Geometry = NOMINAL) -> None:
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

    def predict(self, theta) -> np.ndarray:
        """Readings (N, len(axes)): attained position plus registration, on the measured axes."""
        p = attained_positions(self.servo_deg, self.free, theta, self.nominal, self._start)
        return (p + _registration(self.free, theta))[:, self.axes]

    def jacobian(self, theta) -> np.ndarray:
        """d reading / d theta (N, len(axes), K): central differences (registration columns exact)."""
        theta = np.asarray(theta, dtype=float)
        columns = []
        for k, name in enumerate(self.free):
            if name.startswith("reg_"):
                column = np.zeros((len(self.servo_deg), len(self.axes)))
                if _AXES.index(name[4]) in self.axes:
                    column[:, self.axes.index(_AXES.index(name[4]))] = 1.0
            else:
                step = np.zeros_like(theta)
                step[k] = self._STEP[UNITS[name]]
                column = (self.predict(theta + step) - self.predict(theta - step)) / (2 * step[k])
            columns.append(column)
        return np.stack(columns, axis=-1)
