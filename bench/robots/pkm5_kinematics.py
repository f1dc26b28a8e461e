"""The PKM5 driver's bridge to :mod:`motion.pkm5`: pre-flight checks, steps and strokes, the home pose.

Poses here are (x_mm, y_mm, z_mm, alpha_deg, beta_deg), the bench's units; :mod:`motion.pkm5` works in radians.
The pre-flight refuses, with :class:`bench.errors.UnreachableTarget`, any target that the kinematics do not prove
reachable (IK reachability: mode, orientation range, leg-length and tilt windows), before a byte is sent.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from bench.errors import UnreachableTarget
from motion import pkm5
from motion.errors import MotionInputError

__all__ = [
    "ACTUATOR_BENCH",
    "ASSEMBLED",
    "FIXTURES",
    "home_pose",
    "check_steps",
    "forward_kinematics",
    "home_steps",
    "pose_deg_from_rad",
    "steps_for_pose",
    "steps_for_stroke",
    "stroke_range_mm",
]

#: The robot assembled (every move a pre-flighted pose) or its actuators free-standing on the bench (000 §8.4).
ASSEMBLED, ACTUATOR_BENCH = "assembled", "actuator-bench"
FIXTURES = (ASSEMBLED, ACTUATOR_BENCH)

#: Mode detection tolerance (mm) shared with the simulated plant.
MODE_TOL_MM = 1e-3


def pose_deg_from_rad(pose: np.ndarray) -> np.ndarray:
    out = np.array(pose, dtype=float)
    out[..., 3:] = np.degrees(out[..., 3:])
    return out


def _pose_rad(pose_deg: Any) -> np.ndarray:
    pose = np.array(pose_deg, dtype=float)
    if pose.shape != (5,) or not np.all(np.isfinite(pose)):
        raise UnreachableTarget(
            f"pose = {pose_deg!r}, expected 5 finite numbers (x_mm, y_mm, z_mm, alpha_deg, beta_deg)"
        )
    pose[3:] = np.radians(pose[3:])
    return pose


#: Proved targets remembered per (pose, geometry): a campaign visits a few poses many times (the demo: 5 poses, 450
#: moves), and each proof is an IK solve of 0.35-0.6 ms that the host would otherwise repeat between two moves.
_PROVED_KEPT = 4096


def steps_for_pose(pose_deg: Any, geometry: Any = pkm5.DEFAULT_GEOMETRY) -> tuple[int, ...]:
    """Absolute steps of ``pose_deg``; UnreachableTarget names the pose and every failed check.

    The IK is a pure function of the pose and the geometry (a :class:`motion.pkm5.Geometry`: a frozen dataclass,
    equal and hashed by its values), so a target proved reachable once under a geometry is remembered with its
    steps: the same pose under the same geometry is the same proof. Any other geometry object is solved every time.
    A refused target raises and is never remembered, so it is checked again every time it is asked for."""
    key = _pose_key(pose_deg)
    if type(geometry) is not pkm5.Geometry:  # any other object may be hashed by identity and change meanwhile
        key = None
    else:
        try:
            hash(geometry)
        except TypeError:  # fields given as lists or arrays: it cannot be a key, it is solved every time
            key = None
    if key is None:  # or not 5 finite numbers: the solve below names what is wrong
        return _solve_steps(pose_deg, geometry)
    return _proved_steps(key, geometry)


def _pose_key(pose_deg: Any) -> tuple[float, ...] | None:
    try:
        pose = np.asarray(pose_deg, dtype=float)
    except (TypeError, ValueError):
        return None
    if pose.shape != (5,) or not np.all(np.isfinite(pose)):
        return None
    return tuple(float(v) for v in pose)


@functools.lru_cache(maxsize=_PROVED_KEPT)
def _proved_steps(pose_deg: tuple[float, ...], geometry: Any) -> tuple[int, ...]:
    return _solve_steps(pose_deg, geometry)


def _solve_steps(pose_deg: Any, geometry: Any) -> tuple[int, ...]:
    try:
        result = pkm5.inverse_kinematics(_pose_rad(pose_deg)[None, :], geometry)
    except MotionInputError as exc:
        raise UnreachableTarget(f"pose = {pose_deg!r}: {exc}") from exc
    if not result.reachable[0]:
        raise UnreachableTarget(
            f"pose = {tuple(float(v) for v in np.ravel(pose_deg))} (mm, deg) is not reachable: {result.reason(0)}"
        )
    return tuple(int(s) for s in pkm5.lengths_to_steps(result.lengths_mm, geometry)[0])


def check_steps(steps: tuple[int, ...], geometry: Any = pkm5.DEFAULT_GEOMETRY) -> None:
    """Refuse step targets whose leg lengths leave the windows or whose pose the IK does not call reachable."""
    lengths = pkm5.steps_to_lengths(np.asarray(steps)[None, :], geometry)
    low, high = np.asarray(geometry.leg_min_mm), np.asarray(geometry.leg_max_mm)
    outside = np.flatnonzero((lengths[0] < low) | (lengths[0] > high))
    if outside.size:
        leg = int(outside[0])
        raise UnreachableTarget(
            f"steps = {tuple(steps)}: leg {leg + 1} length {lengths[0, leg]:.3f} mm, expected "
            f"within [{low[leg]:g}, {high[leg]:g}] mm"
        )
    fk = forward_kinematics(lengths, geometry, steps)
    if not fk.converged[0]:
        raise UnreachableTarget(
            f"steps = {tuple(steps)}: no pose fits these leg lengths (FK residual {fk.residual_mm[0]:.3g} mm)"
        )
    ik = pkm5.inverse_kinematics(fk.pose, geometry)
    if not ik.reachable[0]:
        raise UnreachableTarget(
            f"steps = {tuple(steps)}: pose {np.round(pose_deg_from_rad(fk.pose[0]), 3)} "
            f"(mm, deg) is not reachable: {ik.reason(0)}"
        )


def forward_kinematics(lengths_mm: np.ndarray, geometry: Any, steps: Any):
    """FK of leg lengths reached by ``steps`` under ``geometry``. A calibrated geometry is solved in the mode and
    from the pose that the documented geometry gives for the same steps: its asymmetric legs make the length pattern
    of :func:`motion.pkm5.detect_mode` meaningless, and its start table would be sampled anew (minutes)."""
    if geometry == pkm5.DEFAULT_GEOMETRY:
        return pkm5.forward_kinematics(lengths_mm, geometry, mode_tol_mm=MODE_TOL_MM)
    nominal = pkm5.forward_kinematics(pkm5.steps_to_lengths(np.asarray(steps)[None, :]), mode_tol_mm=MODE_TOL_MM)
    return pkm5.forward_kinematics(
        lengths_mm, geometry, initial_pose=nominal.pose, mode=nominal.mode[0], retry_above_mm=0.5
    )


def stroke_range_mm(axis: int, geometry: Any = pkm5.DEFAULT_GEOMETRY) -> tuple[float, float]:
    """Stroke window of actuator ``axis`` (1-6), mm from full retraction: 0 to stroke end - leg-length offset (66)."""
    index = axis - 1
    return 0.0, float(geometry.stroke_end_mm[index] - geometry.leg_length_offset_mm[index])


def steps_for_stroke(axis: Any, stroke_mm: Any, geometry: Any = pkm5.DEFAULT_GEOMETRY) -> int:
    """Absolute step target of one free-standing actuator; UnreachableTarget outside its stroke (actuator bench only:
    on the assembled robot a single leg cannot move alone, 6 legs for 5 DOF)."""
    if isinstance(axis, bool) or not isinstance(axis, (int, np.integer)) or not 1 <= axis <= 6:
        raise UnreachableTarget(f"axis = {axis!r}, expected an actuator number 1-6")
    low, high = stroke_range_mm(int(axis), geometry)
    if (
        isinstance(stroke_mm, bool)
        or not isinstance(stroke_mm, (int, float, np.number))
        or not low <= float(stroke_mm) <= high
    ):
        raise UnreachableTarget(
            f"actuator {axis}: stroke_mm = {stroke_mm!r}, expected a number in [{low:g}, {high:g}] mm"
        )
    index = int(axis) - 1
    counts = round(float(stroke_mm) / geometry.mm_per_step[index])
    return int(counts * geometry.step_direction[index])


def home_steps(geometry: Any = pkm5.DEFAULT_GEOMETRY) -> np.ndarray:
    return pkm5.lengths_to_steps(geometry.home_lengths_mm[None, :], geometry)[0]


@functools.lru_cache(maxsize=8)
def home_pose(geometry: Any = pkm5.DEFAULT_GEOMETRY) -> tuple[float, ...]:
    """The pose at the documents' home (every actuator at its home stroke, 5 mm), from the forward kinematics of
    ``geometry``: (x_mm, y_mm, z_mm, alpha_deg, beta_deg), rounded to 1 um / 1 mdeg (the default geometry gives
    (88.649, 0, 300.937, 0, 0)). The solve starts at the neutral pose, not from the FK's seed table, whose k-d tree
    (scipy.spatial) costs 0.6 s of the desktop app's start-up; the restarts still run if that start fails."""
    fk = pkm5.forward_kinematics(geometry.home_lengths_mm[None, :], geometry, initial_pose=pkm5.NEUTRAL_POSE)
    return tuple(round(float(v), 3) + 0.0 for v in pose_deg_from_rad(fk.pose[0]))
