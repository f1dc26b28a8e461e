"""The PKM5 driver's and simulator's bridge to :mod:`motion.pkm5`: pre-flight checks and the simulated plant.

Poses here are (x_mm, y_mm, z_mm, alpha_deg, beta_deg), the bench's units; :mod:`motion.pkm5` works in radians.
The pre-flight refuses, with :class:`bench.errors.UnreachableTarget`, any target that the kinematics do not prove
reachable (IK reachability: mode, orientation range, leg-length and tilt windows), before a byte is sent.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from bench.errors import UnreachableTarget
from bench.simulators.error_model import ErrorMagnitudes, ErrorModel
from bench.simulators.plant import Plant
from motion import pkm5
from motion.errors import MotionInputError

__all__ = ["ACTUATOR_BENCH", "ASSEMBLED", "FIXTURES", "PKM5_ERRORS", "build_actuator_bench", "build_plant",
           "check_steps", "home_steps", "pose_deg_from_rad", "steps_for_pose", "steps_for_stroke", "stroke_range_mm"]

#: The robot assembled (every move a pre-flighted pose) or its actuators free-standing on the bench (000 §8.4).
ASSEMBLED, ACTUATOR_BENCH = "assembled", "actuator-bench"
FIXTURES = (ASSEMBLED, ACTUATOR_BENCH)

#: Error sizes for AP/RP of the order of the documents' physical tests (pkm5.md §6.8: AP 1.2-1.9 mm, RP 1.6-2.7 mm,
#: angles 0.2-1.9 deg). Joint units mm of leg length; pose units (mm, mm, mm, deg, deg). Actuator noise per
#: Table A.7 (sigma 0.02-0.11 mm); passive-joint play dominates the random part (joint tolerance <= 1 mm, Table 4-2).
PKM5_ERRORS = ErrorMagnitudes(
    scale_sigma=0.003, offset_sigma=0.25, backlash=0.10, noise_sigma=0.05, sag_per_kg=0.005,
    pose_gain_sigma=0.004, pose_play_sigma=(0.6, 0.6, 0.6, 0.35, 0.35),
    pose_sag_per_kg=(0.0, 0.0, -0.03, 0.0, 0.0), pose_offset_sigma=(0.5, 0.5, 0.5, 1.0, 1.0),
)
_MODE_TOL_MM = 1e-3


def pose_deg_from_rad(pose: np.ndarray) -> np.ndarray:
    out = np.array(pose, dtype=float)
    out[..., 3:] = np.degrees(out[..., 3:])
    return out


def _pose_rad(pose_deg: Any) -> np.ndarray:
    pose = np.array(pose_deg, dtype=float)
    if pose.shape != (5,) or not np.all(np.isfinite(pose)):
        raise UnreachableTarget(f"pose = {pose_deg!r}, expected 5 finite numbers (x_mm, y_mm, z_mm, alpha_deg, "
                                "beta_deg)")
    pose[3:] = np.radians(pose[3:])
    return pose


def steps_for_pose(pose_deg: Any, geometry: Any = pkm5.DEFAULT_GEOMETRY) -> tuple[int, ...]:
    """Absolute steps of ``pose_deg``; UnreachableTarget names the pose and every failed check."""
    try:
        result = pkm5.inverse_kinematics(_pose_rad(pose_deg)[None, :], geometry)
    except MotionInputError as exc:
        raise UnreachableTarget(f"pose = {pose_deg!r}: {exc}") from exc
    if not result.reachable[0]:
        raise UnreachableTarget(f"pose = {tuple(float(v) for v in np.ravel(pose_deg))} (mm, deg) is not reachable: "
                                f"{result.reason(0)}")
    return tuple(int(s) for s in pkm5.lengths_to_steps(result.lengths_mm, geometry)[0])


def check_steps(steps: tuple[int, ...], geometry: Any = pkm5.DEFAULT_GEOMETRY) -> None:
    """Refuse step targets whose leg lengths leave the windows or whose pose the IK does not call reachable."""
    lengths = pkm5.steps_to_lengths(np.asarray(steps)[None, :], geometry)
    low, high = np.asarray(geometry.leg_min_mm), np.asarray(geometry.leg_max_mm)
    outside = np.flatnonzero((lengths[0] < low) | (lengths[0] > high))
    if outside.size:
        leg = int(outside[0])
        raise UnreachableTarget(f"steps = {tuple(steps)}: leg {leg + 1} length {lengths[0, leg]:.3f} mm, expected "
                                f"within [{low[leg]:g}, {high[leg]:g}] mm")
    fk = pkm5.forward_kinematics(lengths, geometry, mode_tol_mm=_MODE_TOL_MM)
    if not fk.converged[0]:
        raise UnreachableTarget(f"steps = {tuple(steps)}: no pose fits these leg lengths "
                                f"(FK residual {fk.residual_mm[0]:.3g} mm)")
    ik = pkm5.inverse_kinematics(fk.pose, geometry)
    if not ik.reachable[0]:
        raise UnreachableTarget(f"steps = {tuple(steps)}: pose {np.round(pose_deg_from_rad(fk.pose[0]), 3)} "
                                f"(mm, deg) is not reachable: {ik.reason(0)}")


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
    if isinstance(stroke_mm, bool) or not isinstance(stroke_mm, (int, float, np.number)) \
            or not low <= float(stroke_mm) <= high:
        raise UnreachableTarget(f"actuator {axis}: stroke_mm = {stroke_mm!r}, expected a number in "
                                f"[{low:g}, {high:g}] mm")
    index = int(axis) - 1
    counts = round(float(stroke_mm) / geometry.mm_per_step[index])
    return int(counts * geometry.step_direction[index])


def build_actuator_bench(seed: int, *, ideal: bool = False, geometry: Any = pkm5.DEFAULT_GEOMETRY):
    """The six actuators free-standing (000 §8.4): ``bench(steps, load_kg) -> true strokes`` (6,), mm.

    Each actuator's attained leg length comes from the same seeded joint errors as :func:`build_plant` (scale,
    offset, backlash, noise; no payload on a free-standing actuator), reported as stroke from full retraction.
    """
    from bench.simulators.error_model import JointMemory

    offsets = np.asarray(geometry.leg_length_offset_mm, dtype=float)
    model = ErrorModel.ideal(6, 5) if ideal else ErrorModel.draw(PKM5_ERRORS, 6, seed, offsets)
    rng = np.random.default_rng([seed, 1])
    memory: list[JointMemory] = []

    def true_strokes(steps: np.ndarray, load_kg: float) -> np.ndarray:
        lengths = pkm5.steps_to_lengths(np.asarray(steps)[None, :], geometry)[0]
        if not memory:
            memory.append(JointMemory(lengths))
        direction = memory[0].update(lengths)
        return model.true_joints(lengths, direction, 0.0, rng) - offsets

    true_strokes.model = model  # type: ignore[attr-defined]  # the drawn errors, for tests against the truth
    return true_strokes


def home_steps(geometry: Any = pkm5.DEFAULT_GEOMETRY) -> np.ndarray:
    return pkm5.lengths_to_steps(geometry.home_lengths_mm[None, :], geometry)[0]


def build_plant(seed: int, *, ideal: bool = False, geometry: Any = pkm5.DEFAULT_GEOMETRY,
                true_geometry: Any = None) -> Plant:
    """Steps -> leg lengths -> seeded errors -> least-squares FK -> pose errors; pose in mm and degrees.

    With ``true_geometry`` (a perturbed :class:`motion.pkm5.Geometry`, e.g. from
    :func:`bench.simulators.true_geometry.true_geometry`) the robot moves by that geometry's lengths and FK, and the
    error model's stand-ins for geometry (joint offset and scale, pose gain and bias) are zeroed; backlash, noise,
    sag and play stay.
    """
    moved_by = geometry if true_geometry is None else true_geometry

    def joints_of(steps: np.ndarray) -> np.ndarray:
        return pkm5.steps_to_lengths(steps[None, :], moved_by)[0]

    def forward(lengths: np.ndarray, commanded: np.ndarray, previous: np.ndarray | None) -> np.ndarray | None:
        if true_geometry is not None:  # the commanded mode shows in the nominal lengths (the true pairs differ)
            commanded = pkm5.steps_to_lengths(pkm5.lengths_to_steps(commanded[None, :], moved_by), geometry)[0]
        mode = pkm5.detect_mode(commanded[None, :], _MODE_TOL_MM)[0]
        if true_geometry is not None:  # start from the nominal solution (no seed table for a perturbed geometry)
            start = pkm5.forward_kinematics(commanded[None, :], geometry, mode=mode, residual_tol_mm=2.0,
                                            max_iter=200).pose[0]
        elif previous is not None:
            start = np.r_[previous[:3], np.radians(previous[3:])]
        else:
            start = None
        # true lengths never fit exactly (6 legs, 3-4 unknowns): retrying every inexact fit from the restart guesses
        # would trade the near solution for a far branch with a smaller residual
        retry = 1e-9 if true_geometry is None else 0.5
        fk = pkm5.forward_kinematics(lengths[None, :], moved_by, initial_pose=start, mode=mode,
                                     residual_tol_mm=2.0, retry_above_mm=retry,
                                     max_iter=50 if true_geometry is None else 200)
        return pose_deg_from_rad(fk.pose[0]) if fk.converged[0] else None

    model = (ErrorModel.ideal(6, 5) if ideal else
             ErrorModel.draw(PKM5_ERRORS, 6, seed, np.asarray(geometry.leg_length_offset_mm)))
    if true_geometry is not None:
        model = dataclasses.replace(model, offset=np.zeros(6), scale=np.zeros(6), pose_gain=np.zeros((5, 5)),
                                    pose_offset=np.zeros(5))
    home_fk = pkm5.forward_kinematics(geometry.home_lengths_mm[None, :], geometry)
    return Plant(joints_of, forward, model, pose_deg_from_rad(home_fk.pose[0]), seed)
