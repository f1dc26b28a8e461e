"""The simulated mechanism behind a simulated controller: commanded joints -> true attained pose.

A :class:`Plant` chains three robot-specific or shared pieces: ``joints_of`` (controller units -> actuated joint
values, e.g. steps -> leg lengths in mm), the seeded :class:`bench.simulators.error_model.ErrorModel`, and ``forward``
(forward kinematics from :mod:`motion`, returning the pose in mm and degrees). Random terms come from a generator
seeded from the robot seed, so a simulated campaign is reproducible.
"""

from __future__ import annotations

import copy
import logging
from collections.abc import Callable

import numpy as np

from bench.simulators.error_model import ErrorModel, JointMemory

__all__ = ["Plant"]

_log = logging.getLogger(__name__)

#: Distinct commands whose attained pose is kept as a warm start (a campaign revisits a few poses many times).
_ATTAINED_KEPT = 1024


class Plant:
    """Callable ``plant(command, load_kg) -> true pose`` (pose in mm and degrees).

    Parameters
    ----------
    joints_of : callable
        ``(J,) controller command -> (J,) joint values`` in the error model's joint units.
    forward : callable
        ``(joints (J,), commanded_joints (J,), start_pose (P,) or None) -> pose (P,)``, or ``None`` if the
        kinematics fail (the commanded joints tell the solver which motion mode was meant). ``start_pose`` is a
        warm start: the pose last attained at the same command (it differs only by the random errors, so an
        iterative solver needs the fewest iterations from there), else the last attained pose, else None.
    model : ErrorModel
        Systematic errors and random-error sizes.
    reference_pose : array (P,)
        Pose about which the pose-dependent error is zero (the home pose).
    seed : int
        Seed of the per-move random stream.
    warm_up : callable, optional
        ``warm_up(wait_s)``: work a simulator starts (:meth:`warm_up`) once it is built, not while it is being
        built, e.g. loading a compiled kernel on a thread; ``wait_s`` > 0 waits for it up to that long.
    """

    def __init__(
        self,
        joints_of: Callable[[np.ndarray], np.ndarray],
        forward: Callable[[np.ndarray, np.ndarray, np.ndarray | None], np.ndarray | None],
        model: ErrorModel,
        reference_pose: np.ndarray,
        seed: int,
        warm_up: Callable[[], None] | None = None,
    ) -> None:
        self.joints_of = joints_of
        self.forward = forward
        self.model = model
        self.reference_pose = np.asarray(reference_pose, dtype=float)
        self._rng = np.random.default_rng([seed, 1])
        self._memory: JointMemory | None = None
        self._previous: np.ndarray | None = None
        #: the attained (perturbed) joint values of the last call, e.g. the true leg lengths in mm
        self.true_joints: np.ndarray | None = None
        self._prepared: tuple[np.ndarray, float, Plant, np.ndarray] | None = None
        self._attained: dict[bytes, np.ndarray] = {}  # commanded joints -> the pose last attained there
        self._warm_up = warm_up

    def warm_up(self, wait_s: float = 0.0) -> None:
        """Start the plant's deferred start-up work (idempotent; a no-op for most plants); with ``wait_s`` > 0
        return once it is done or ``wait_s`` has passed."""
        if self._warm_up is not None:
            self._warm_up(wait_s)

    def prepare(self, command: np.ndarray, load_kg: float) -> None:
        """Compute now what the next call ``plant(command, load_kg)`` will return, leaving the plant's state as is.

        A simulator calls this when it accepts a move (the kinematics take milliseconds), so the reply at the move's
        end does not wait for them. The work runs on a copy of the random stream and the joint memory; the next
        call with the same command and load adopts the copy's state and result, which are exactly what that call
        would have computed. Any other call discards the prepared result and computes as usual.
        """
        trial = copy.copy(self)
        # JointMemory.update rebinds its arrays, never writes into them: a shallow copy is a copy; the random
        # stream is copied through its state (a third of a deepcopy's time, which goes through pickle)
        trial._rng, trial._memory = _copied_rng(self._rng), copy.copy(self._memory)
        trial._attained = dict(self._attained)
        trial._prepared = None
        command = np.array(command, copy=True)
        pose = trial._advance(command, load_kg)
        self._prepared = (command, float(load_kg), trial, pose)

    def __call__(self, command: np.ndarray, load_kg: float) -> np.ndarray:
        prepared, self._prepared = self._prepared, None
        if prepared is not None and prepared[1] == float(load_kg) and np.array_equal(prepared[0], command):
            _, _, trial, pose = prepared
            self._rng, self._memory, self._previous, self.true_joints, self._attained = (
                trial._rng,
                trial._memory,
                trial._previous,
                trial.true_joints,
                trial._attained,
            )
            return pose
        return self._advance(command, load_kg)

    def _advance(self, command: np.ndarray, load_kg: float) -> np.ndarray:
        """One move of the mechanism: the true pose for ``command``; advances the random stream and joint memory."""
        joints = np.asarray(self.joints_of(np.asarray(command)), dtype=float)
        if self._memory is None:
            self._memory = JointMemory(joints)
        direction = self._memory.update(joints)
        true_joints = self.model.true_joints(joints, direction, load_kg, self._rng)
        self.true_joints = true_joints
        key = joints.tobytes()
        start = self._attained.get(key, self._previous)
        pose = self.forward(true_joints, joints, start)
        if pose is None:  # the perturbed joints left the FK's domain: fall back to the nominal joints
            _log.warning("forward kinematics failed for perturbed joints %s; using the commanded ones", true_joints)
            pose = self.forward(joints, joints, start)
        if pose is None:
            raise ValueError(f"forward kinematics failed for commanded joints {joints}")
        self._previous = np.asarray(pose, dtype=float)
        self._attained.pop(key, None)
        self._attained[key] = self._previous
        if len(self._attained) > _ATTAINED_KEPT:
            del self._attained[next(iter(self._attained))]  # the command visited longest ago
        return self.model.true_pose(self._previous, self.reference_pose, load_kg, self._rng)


def _copied_rng(rng: np.random.Generator) -> np.random.Generator:
    """An independent generator at the same point of the same stream as ``rng``."""
    copied = np.random.Generator(type(rng.bit_generator)())
    copied.bit_generator.state = rng.bit_generator.state
    return copied
