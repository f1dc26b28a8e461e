"""Geometric error model of the PKM for kinematic calibration: a named parameter vector and the measurement model.

The parameters are deviations from a nominal :class:`~motion.pkm5.geometry.Geometry` (the documented robot unless
told otherwise), each with its unit in its name:

* ``leg_offset_<i>_mm`` (i = 1..6): added to ``leg_length_offset_mm[i]``, the length |BC| at zero stroke;
* ``scale_<i>``: relative error of the lead (``mm_per_full_step[i] * (1 + scale_i)``), dimensionless;
* ``oa_<pair>_<axis>_mm`` (pair 12, 34, 56): base joint positions A, global frame;
* ``pd_<leg>_<axis>_mm`` (12, 34, 5, 6): platform joint positions D, end-effector frame;
* ``reg_<axis>_mm`` (x, y, z): registration of a relative instrument (the mice measure displacements from home),
  a constant added to every predicted position; not a geometry field.

The measurement model is forward (pkm5.md §4.3, least squares over the six legs): commanded steps ``s`` give leg
lengths ``L(s; theta) = L0 + s * dir * CR (1 + scale)`` and the attained pose is
``p(theta) = argmin_p |IK(p; theta) - L(s; theta)|^2`` within the commanded motion mode. Its Jacobian comes from the
implicit function theorem on the FK's normal equations ``F = J_p^T (IK(p; theta) - L(s; theta)) = 0``:
``dp/dtheta = -(dF/dp)^{-1} dF/dtheta`` with ``J_p`` the exact pose Jacobian of the IK restricted to the mode's
columns (:func:`motion.pkm5.jacobian.jacobian`) and both derivatives of F by central differences of closed forms
(smooth, so a 1e-4 mm step gives ~1e-8 relative accuracy); no FK solve is needed for the Jacobian.
Forward residuals suit position-only and relative measurements (mice, laser grid) where the orientation is not
measured; the calibration literature (methods-turn2.md §1.1) prefers IK residuals only when the full pose is known.
"""

from __future__ import annotations

import dataclasses
import functools
import types
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from motion import dual, kernels
from motion.errors import MotionInputError
from motion.pkm5.fk import MODES, forward_kinematics
from motion.pkm5.geometry import DEFAULT_GEOMETRY, Geometry, steps_to_lengths
from motion.pkm5.ik import leg_lengths
from motion.pkm5.jacobian import jacobian

__all__ = [
    "PARAMETERS",
    "REGISTRATION",
    "TOLERANCES",
    "UNITS",
    "apply_parameters",
    "compensation_geometry",
    "geometry_from_calibration",
    "parameter_deviations",
    "modes_of_poses",
    "tolerance",
    "ForwardModel",
]

_AXES = ("x", "y", "z")
_JOINT_FIELDS = ("oa_12", "oa_34", "oa_56", "pd_12", "pd_34", "pd_5", "pd_6")
#: Registration unknowns of a relative instrument (mm).
REGISTRATION = tuple(f"reg_{axis}_mm" for axis in _AXES)
#: Every geometric parameter, in the order the default free set is built (joint zeros first, then scales, then
#: the joint positions, pkm5.md §2.6: the fields the documents never give come first).
PARAMETERS = (
    tuple(f"leg_offset_{i}_mm" for i in range(1, 7))
    + tuple(f"scale_{i}" for i in range(1, 7))
    + tuple(f"{field}_{axis}_mm" for field in _JOINT_FIELDS for axis in _AXES)
)
#: Unit of each parameter (``1`` for the dimensionless scale).
UNITS = {name: ("1" if name.startswith("scale_") else "mm") for name in PARAMETERS + REGISTRATION}
_FD_STEP = {"mm": 1e-4, "1": 1e-6}
#: Manufacturing tolerances, 1 sigma per parameter family: joint positions 0.3 mm (printed parts, hand-assembled
#: joints: sub-millimetre), leg zero offsets 0.3 mm (set by hand), lead 0.5 % (lead screws). The prior of the
#: maximum a posteriori identification (docs/calibration.md) and the size of the simulator's seeded true geometry.
TOLERANCES = {"leg_offset": 0.3, "scale": 0.005, "joint": 0.3}


def tolerance(name: str) -> float:
    """The 1-sigma tolerance of parameter ``name`` (:data:`TOLERANCES`; ``inf`` for the registration, which the
    instrument's placement sets and no drawing bounds)."""
    _check_names((name,))
    if name.startswith("reg_"):
        return float("inf")
    if name.startswith("leg_offset_"):
        return TOLERANCES["leg_offset"]
    return TOLERANCES["scale"] if name.startswith("scale_") else TOLERANCES["joint"]


#: Distance from the documented geometry's pose beyond which a warm-started FK solution is taken for a branch jump.
_BRANCH_JUMP_MM = 20.0


def _bumped_joints(geometry: Geometry, names: Sequence[str], step: float, rows: int) -> Any:
    """One geometry for a batched IK of ``2 * len(names) * rows`` poses: ``geometry`` with joint parameter
    ``names[i]`` moved by +``step`` (rows ``2i * rows ..``) and by -``step`` (rows ``(2i + 1) * rows ..``); its joint
    vectors hold per-row arrays (the IK broadcasts them), the other fields are ``geometry``'s."""
    fields = {f.name: getattr(geometry, f.name) for f in dataclasses.fields(geometry)}
    for field in _JOINT_FIELDS:
        values = np.tile(np.asarray(fields[f"{field}_mm"], dtype=float), (2 * len(names), 1))  # (2K, 3)
        for i, name in enumerate(names):
            if name[:-5] == field:
                values[2 * i : 2 * i + 2, _AXES.index(name[-4])] += (step, -step)
        fields[f"{field}_mm"] = tuple(np.repeat(values[:, axis], rows) for axis in range(3))
    return types.SimpleNamespace(**fields)


def _check_names(names: Iterable[str]) -> tuple[str, ...]:
    names = tuple(names)
    unknown = [n for n in names if n not in UNITS]
    if unknown:
        raise MotionInputError(
            f"calibration parameter {unknown[0]!r} is not a pkm5 parameter; expected one of "
            f"leg_offset_1_mm..leg_offset_6_mm, scale_1..scale_6, oa_12_x_mm.., pd_6_z_mm, "
            f"reg_x_mm..reg_z_mm"
        )
    if len(set(names)) != len(names):
        raise MotionInputError(f"calibration parameters {list(names)} name one parameter twice")
    return names


def apply_parameters(names: Iterable[str], values: ArrayLike, geometry: Geometry = DEFAULT_GEOMETRY) -> Geometry:
    """The geometry with the deviations ``values`` of parameters ``names`` added (registration names ignored)."""
    names = _check_names(names)
    values = np.asarray(values, dtype=float).reshape(len(names))
    offsets = np.array(geometry.leg_length_offset_mm, dtype=float)
    lead = np.array(geometry.mm_per_full_step, dtype=float)
    joints = {field: np.array(getattr(geometry, f"{field}_mm"), dtype=float) for field in _JOINT_FIELDS}
    for name, value in zip(names, values):
        if name.startswith("leg_offset_"):
            offsets[int(name[11]) - 1] += value
        elif name.startswith("scale_"):
            index = int(name[6]) - 1
            lead[index] = geometry.mm_per_full_step[index] * (1.0 + value)
        elif not name.startswith("reg_"):
            field, axis = name[:-5], name[-4]
            joints[field][_AXES.index(axis)] += value
    return geometry.replace(
        leg_length_offset_mm=tuple(offsets),
        mm_per_full_step=tuple(lead),
        **{f"{field}_mm": tuple(v) for field, v in joints.items()},
    )


def parameter_deviations(geometry: Geometry, nominal: Geometry = DEFAULT_GEOMETRY) -> dict[str, float]:
    """Every parameter of :data:`PARAMETERS` as the deviation of ``geometry`` from ``nominal``."""
    out = {}
    for i in range(6):
        out[f"leg_offset_{i + 1}_mm"] = geometry.leg_length_offset_mm[i] - nominal.leg_length_offset_mm[i]
    for i in range(6):
        out[f"scale_{i + 1}"] = geometry.mm_per_full_step[i] / nominal.mm_per_full_step[i] - 1.0
    for field in _JOINT_FIELDS:
        for k, axis in enumerate(_AXES):
            out[f"{field}_{axis}_mm"] = getattr(geometry, f"{field}_mm")[k] - getattr(nominal, f"{field}_mm")[k]
    return {name: float(value) for name, value in out.items()}


def geometry_from_calibration(params: Mapping[str, Any], nominal: Geometry = DEFAULT_GEOMETRY) -> Geometry:
    """The calibrated geometry of a stored kinematic calibration's parameters (``{"parameters": {name: {"value":
    ...}}}``, as ``bench calibrate`` stores them); registration entries are not geometry and are skipped."""
    try:
        entries = {name: float(entry["value"]) for name, entry in params["parameters"].items()}
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise MotionInputError(
            f"kinematic calibration parameters: {exc!r}, expected {{'parameters': {{name: {{'value': number}}}}}}}}"
        ) from None
    geometric = {n: v for n, v in entries.items() if not n.startswith("reg_")}
    return apply_parameters(tuple(geometric), tuple(geometric.values()), nominal)


def compensation_geometry(params: Mapping[str, Any], nominal: Geometry = DEFAULT_GEOMETRY) -> Geometry:
    """The geometry a compensated run commands by: :func:`geometry_from_calibration` in the instrument's frame.

    The calibration predicts a measurement as ``m = FK(s; theta) + r`` (``r`` the registration ``reg_*_mm``).
    Moving every base joint A by ``r`` moves every attained pose by ``r`` (the leg lengths depend only on the joints'
    relative positions: ``IK(p + r; A + r) = IK(p; A)``), so ``FK(s; theta, A + r) = FK(s; theta) + r``: with the
    registration added to ``oa_12``, ``oa_34`` and ``oa_56`` the geometry's own frame is the instrument's, and its
    IK of a target ``T`` gives the steps whose predicted measurement is ``T``.
    """
    geometry = geometry_from_calibration(params, nominal)
    shift = np.zeros(3)
    for name, entry in params["parameters"].items():
        if name in REGISTRATION:
            shift[_AXES.index(name[4])] = float(entry["value"])
    return geometry.replace(
        **{
            f"{field}_mm": tuple(np.asarray(getattr(geometry, f"{field}_mm")) + shift)
            for field in ("oa_12", "oa_34", "oa_56")
        }
    )


def modes_of_poses(poses: ArrayLike) -> np.ndarray:
    """Motion mode of commanded poses (N, 5; angles in any unit): 'alpha' if alpha != 0, 'beta' if beta != 0."""
    p = np.asarray(poses, dtype=float).reshape(-1, 5)
    return np.where(p[:, 3] != 0, "alpha", np.where(p[:, 4] != 0, "beta", "translation")).astype(object)


class ForwardModel:
    """Predicted measured coordinates of the attained poses as a function of the free parameters.

    Parameters
    ----------
    steps : array_like (N, 6)
        Commanded absolute steps of each measured pose.
    modes : array_like (N,) of str
        Motion mode of each commanded pose ('translation', 'alpha', 'beta'; :func:`modes_of_poses`).
    free : sequence of str
        Names of the free parameters (:data:`PARAMETERS` and :data:`REGISTRATION`).
    axes : sequence of int
        Pose coordinates the instrument measures (0, 1, 2 = x, y, z in mm; the mice: all three positions).
    nominal : Geometry
        The geometry the deviations are taken from.
    engine : {'auto', 'numpy', 'compiled'}
        The forward kinematics' engine (:func:`motion.pkm5.forward_kinematics`); 'auto' is compiled when numba is
        installed.
    """

    def __init__(
        self,
        steps: ArrayLike,
        modes: ArrayLike,
        free: Iterable[str],
        axes: Sequence[int] = (0, 1, 2),
        nominal: Geometry = DEFAULT_GEOMETRY,
        engine: str = "auto",
    ) -> None:
        # 'auto': the compiled FK whenever numba is installed, whatever the batch size (the FK's own 'auto' waits
        # for 10,000 poses): an identification solves the same 30-100 poses some 30 times, and numpy's per-call
        # overhead, not arithmetic, is its time (100 poses: 4.9 s numpy, 0.76 s compiled, equal to 1e-5)
        self.steps = np.asarray(steps, dtype=float).reshape(-1, 6)
        self.engine = "compiled" if kernels.use_compiled(engine, len(self.steps), threshold=0) else "numpy"
        self.modes = np.asarray(modes, dtype=object).reshape(-1)
        if len(self.modes) != len(self.steps):
            raise MotionInputError(f"modes has {len(self.modes)} entries for {len(self.steps)} poses")
        bad = set(self.modes) - set(MODES)
        if bad:
            raise MotionInputError(f"mode = {sorted(bad)[0]!r}, expected one of {sorted(MODES)}")
        self.free = _check_names(free)
        self.axes = tuple(int(a) for a in axes)
        if not self.axes or any(a not in (0, 1, 2) for a in self.axes):
            raise MotionInputError(f"axes = {axes!r}, expected a subset of (0, 1, 2) (x, y, z)")
        self.nominal = nominal
        self._starts: dict[str, np.ndarray] = {}  # per mode: the documented geometry's poses, the FK's start
        self._last: dict[str, np.ndarray] = {}  # per mode: the poses of the latest evaluation (warm start)
        self._evaluated: tuple[np.ndarray, np.ndarray] | None = None  # (theta, poses) of the latest evaluation

    @property
    def bound(self) -> np.ndarray:
        """Largest plausible |deviation| of each free parameter, the solver's box: 5 mm, 5 % of the lead, 20 mm
        of registration (ten times the true-geometry sizes; a solution at the box is a model or data error)."""
        return np.array([0.05 if UNITS[n] == "1" else 20.0 if n.startswith("reg_") else 5.0 for n in self.free])

    @property
    def units(self) -> tuple[str, ...]:
        return tuple(UNITS[name] for name in self.free)

    def poses(self, theta: ArrayLike) -> np.ndarray:
        """Attained poses (N, 5; mm, rad) under parameters ``theta``; NaN rows where the FK fails."""
        theta = np.asarray(theta, dtype=float)
        if self._evaluated is not None and np.array_equal(self._evaluated[0], theta):
            return self._evaluated[1].copy()  # the solver asks for the Jacobian where it just evaluated
        geometry = apply_parameters(self.free, theta, self.nominal)
        lengths = steps_to_lengths(self.steps, geometry)
        out = np.full((len(self.steps), 5), np.nan)
        for mode in MODES:
            rows = np.flatnonzero(self.modes == mode)
            if rows.size == 0:
                continue
            if mode not in self._starts:
                # every solve starts from the documented geometry's solution: its k-d seed tables are cached (a
                # perturbed geometry's alpha plane moves and rejection-sampling a new table takes minutes), and a
                # fixed start keeps each solve on the same branch whatever trial parameters came before
                self._starts[mode] = forward_kinematics(
                    steps_to_lengths(self.steps[rows], DEFAULT_GEOMETRY),
                    DEFAULT_GEOMETRY,
                    mode=mode,
                    residual_tol_mm=2.0,
                    max_iter=200,
                    engine=self.engine,
                ).pose
            # warm start: the poses of the last evaluation (a nearby trial: the solver's steps are small), which
            # cuts the LM iterations several-fold; a row that did not converge there starts from the fixed start
            last = self._last.get(mode)
            start = self._starts[mode] if last is None else np.where(np.isfinite(last), last, self._starts[mode])
            fk = forward_kinematics(
                lengths[rows],
                geometry,
                initial_pose=start,
                mode=mode,
                residual_tol_mm=2.0,
                retry_above_mm=0.5,
                max_iter=200,
                engine=self.engine,
            )
            solved = np.where(fk.converged[:, None], fk.pose, np.nan)
            # a warm start can walk a pose onto another FK branch (seen at a beta pose: 57 mm away, and the
            # solver then stays in that basin); sub-millimetre deviations move a pose by a few mm at most, so a
            # row far from the documented geometry's pose is solved again from that fixed start
            far = ~(np.linalg.norm(solved[:, :3] - self._starts[mode][:, :3], axis=1) <= _BRANCH_JUMP_MM)
            if last is not None and far.any():
                again = forward_kinematics(
                    lengths[rows][far],
                    geometry,
                    initial_pose=self._starts[mode][far],
                    mode=mode,
                    residual_tol_mm=2.0,
                    retry_above_mm=0.5,
                    max_iter=200,
                    engine=self.engine,
                )
                solved[far] = np.where(again.converged[:, None], again.pose, np.nan)
            out[rows] = solved
            self._last[mode] = out[rows]
        self._evaluated = (theta.copy(), out.copy())
        return out

    def _registration(self, theta: ArrayLike) -> np.ndarray:
        shift = np.zeros(3)
        for name, value in zip(self.free, np.asarray(theta, dtype=float)):
            if name.startswith("reg_"):
                shift[_AXES.index(name[4])] = value
        return shift

    def predict(self, theta: ArrayLike) -> np.ndarray:
        """Predicted measured coordinates (N, len(axes)), mm."""
        positions = self.poses(theta)[:, :3] + self._registration(theta)
        return positions[:, list(self.axes)]

    def _stationarity(self, p: np.ndarray, geometry: Any, lengths: np.ndarray) -> np.ndarray:
        """F(p) = J_m^T (IK(p; geometry) - lengths) per row, (M, 5) (zero columns outside the mode): the normal
        equations the least-squares FK solves, F = 0 at every attained pose. ``p`` (M, 5) is a whole number of
        copies of the pose set, ``geometry`` a Geometry or :func:`_bumped_joints` (one geometry per copy),
        ``lengths`` (M, 6) the commanded leg lengths; one batched dual-number pass gives IK and J_m together."""
        x, y, z, alpha, beta = dual.seed(p)
        legs, _ = leg_lengths(x, y, z, alpha, beta, geometry=geometry, with_tilt=False)
        residual = np.stack([leg.value for leg in legs], -1) - lengths
        pose_jac = np.stack([leg.grad for leg in legs], 1)
        out = np.einsum("nlc,nl->nc", pose_jac, residual)
        return out * np.tile(self._mode_mask, (len(p) // len(self._mode_mask), 1))

    @functools.cached_property
    def _mode_mask(self) -> np.ndarray:
        """(N, 5): 1 for the pose columns that move in each pose's mode (x, y, z and the mode's angle); computed once,
        the modes being fixed at construction."""
        mask = np.ones((len(self.modes), 5))
        for mode, angle in MODES.items():
            rows = self.modes == mode
            mask[rows, 3] = angle == 3
            mask[rows, 4] = angle == 4
        return mask

    def _dfdp(self, p: np.ndarray, geometry: Any, lengths: np.ndarray) -> np.ndarray:
        """dF/dp per pose (N, 5, 5) by central differences, the ten bumped pose sets in one batch."""
        n = len(p)
        steps = (1e-4, 1e-4, 1e-4, 1e-6, 1e-6)
        bumps = np.concatenate([np.diag(steps), -np.diag(steps)])  # (10, 5): +h_c, then -h_c
        bumped = (p[None, :, :] + bumps[:, None, :]).reshape(-1, 5)
        f = self._stationarity(bumped, geometry, np.tile(lengths, (10, 1))).reshape(2, 5, n, 5)
        return ((f[0] - f[1]) / np.reshape(2.0 * np.asarray(steps), (5, 1, 1))).transpose(1, 2, 0)

    def fold_ratio(self, theta: ArrayLike) -> np.ndarray:
        """Per pose, smallest / largest eigenvalue of the symmetric part of dF/dp over the mode's columns (raw mm and
        rad units): near 0 the pose is near a fold of the FK, where nearby geometries' solves may change branch (so a
        fit through it meets a barrier; docs/calibration.md, the MAP candidate)."""
        theta = np.asarray(theta, dtype=float)
        geometry = apply_parameters(self.free, theta, self.nominal)
        dfdp = self._dfdp(np.nan_to_num(self.poses(theta)), geometry, steps_to_lengths(self.steps, geometry))
        mask = self._mode_mask
        out = np.empty(len(dfdp))
        for i, block in enumerate(dfdp):
            cols = np.flatnonzero(mask[i])
            eig = np.linalg.eigvalsh(0.5 * (block[np.ix_(cols, cols)] + block[np.ix_(cols, cols)].T))
            out[i] = eig[0] / eig[-1]
        return out

    def jacobian(self, theta: ArrayLike, poses: np.ndarray | None = None) -> np.ndarray:
        """d predict / d theta, shape (N, len(axes), len(free)), exact up to central-difference error.

        Implicit function theorem on the FK's normal equations F(p, theta) = 0 (:meth:`_stationarity`):
        ``dp/dtheta = -(dF/dp)^{-1} dF/dtheta`` over the mode's pose columns, with both derivatives by central
        differences of closed forms (no FK solve). dF/dp is ``J^T J`` plus the residual-curvature term that a
        Gauss-Newton Jacobian drops (~1 % when six legs over-determine three or four pose unknowns).
        """
        theta = np.asarray(theta, dtype=float)
        p = np.nan_to_num(self.poses(theta) if poses is None else poses)
        n, k = len(p), len(self.free)
        geometry = apply_parameters(self.free, theta, self.nominal)
        lengths = steps_to_lengths(self.steps, geometry)
        dfdp = self._dfdp(p, geometry, lengths)
        mask = self._mode_mask
        dfdt = np.zeros((n, 5, k))
        # the leg zeros and leads only move the commanded lengths L(s; theta), not IK(p; theta) nor its Jacobian:
        # dF/dtheta = -J_m^T dL/dtheta in closed form, dL_i/d offset_i = 1, dL_i/d scale_i = s_i dir_i CR_i
        pose_jac = jacobian(p, geometry) * mask[:, None, :]
        nominal_step = np.asarray(self.nominal.mm_per_step) * np.asarray(self.nominal.step_direction)
        joints = []
        for j, name in enumerate(self.free):
            if name.startswith("reg_"):
                continue
            if name.startswith(("leg_offset_", "scale_")):
                leg = int(name[-4 if name.endswith("_mm") else -1]) - 1
                dlength = 1.0 if name.startswith("leg_offset_") else self.steps[:, leg] * nominal_step[leg]
                dfdt[:, :, j] = -pose_jac[:, leg, :] * np.reshape(dlength, (-1, 1))
            else:
                joints.append(j)
        if joints:
            # the joint positions move IK(p; theta) and J_m: central differences, every bumped geometry (+h, -h per
            # joint parameter) in one batched evaluation, since numpy's per-call overhead dominates 30-100 poses
            h = _FD_STEP["mm"]
            bumped = _bumped_joints(geometry, [self.free[j] for j in joints], h, n)
            f = self._stationarity(
                np.tile(p, (2 * len(joints), 1)), bumped, np.tile(lengths, (2 * len(joints), 1))
            ).reshape(len(joints), 2, n, 5)
            dfdt[:, :, joints] = ((f[:, 0] - f[:, 1]) / (2 * h)).transpose(1, 2, 0)
        # outside the mode's columns put an identity block, so the solve leaves those pose derivatives at zero
        dfdp = dfdp + np.einsum("nc,cd->ncd", 1.0 - mask, np.eye(5))
        dpose = -np.linalg.solve(dfdp, dfdt)
        for j, name in enumerate(self.free):
            if name.startswith("reg_"):
                dpose[:, _AXES.index(name[4]), j] = 1.0
        return dpose[:, list(self.axes), :]
