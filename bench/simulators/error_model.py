"""Seeded error model of a simulated robot: what turns commanded joint values into the attained pose.

Systematic errors are drawn once per robot from a seed (:meth:`ErrorModel.draw`); random errors are drawn per move
from a separate stream, so a campaign is reproducible from ``(seed, commands)``. Joint-space terms act on the
actuated joint (PKM5: leg length in mm; delta4: servo angle in degrees); pose-space terms act on the pose the
forward kinematics returns (mm for positions, the kinematics' own angle unit for orientations).

For joint i with commanded value q_i, direction of the last motion d_i (+1/-1/0) and payload m (kg):

.. math:: q_i^{true} = q_i + o_i + s_i\\,(q_i - z_i) - \\tfrac12 b_i d_i - k_i m + \\varepsilon_i,
          \\quad \\varepsilon_i \\sim N(0, \\sigma_q^2)

with z_i the joint value about which the scale error acts (PKM5: zero stroke; delta4: mid-range servo angle),
and for the pose p = FK(q^true), with p_0 the reference (home) pose:

.. math:: p^{true} = p + e + G\\,(p - p_0) + m\\,c + \\eta, \\quad \\eta \\sim N(0, \\operatorname{diag}\\sigma_p^2)

``e`` is a constant assembly bias, ``G`` a small random matrix (pose-dependent, anisotropic error, e.g.
mis-calibrated geometry), ``c`` the sag per kg of payload, and ``eta`` the play of the passive joints (the dominant
random term on both documented robots).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["ErrorMagnitudes", "ErrorModel", "JointMemory"]


@dataclass(frozen=True)
class ErrorMagnitudes:
    """1-sigma sizes of each error term, in joint units (J) and pose units (P) of the robot.

    Parameters
    ----------
    scale_sigma : float
        Relative scale error of each joint (dimensionless).
    offset_sigma : float
        Zero offset of each joint, joint units.
    backlash : float
        Mean full backlash of each joint, joint units (each joint draws 0.5x-1.5x this).
    noise_sigma : float
        Repeatability noise per move and joint, joint units.
    sag_per_kg : float
        Joint compression per kg of payload, joint units/kg.
    pose_gain_sigma : float
        Entries of the pose-dependent gain matrix G (dimensionless).
    pose_play_sigma : tuple of float
        Passive-joint play per pose coordinate, pose units.
    pose_sag_per_kg : tuple of float
        Pose drift per kg of payload, pose units/kg (e.g. z drops).
    pose_offset_sigma : tuple of float
        Constant pose bias of the assembled robot (end-effector mounting, frame alignment), pose units.
    """

    scale_sigma: float
    offset_sigma: float
    backlash: float
    noise_sigma: float
    sag_per_kg: float
    pose_gain_sigma: float
    pose_play_sigma: tuple[float, ...]
    pose_sag_per_kg: tuple[float, ...]
    pose_offset_sigma: tuple[float, ...]


@dataclass(frozen=True)
class ErrorModel:
    """The systematic errors of one simulated robot plus its random-error sizes (see module docstring)."""

    scale: np.ndarray  # (J,)
    offset: np.ndarray  # (J,)
    backlash: np.ndarray  # (J,)
    noise_sigma: float
    sag_per_kg: np.ndarray  # (J,)
    pose_gain: np.ndarray  # (P, P)
    pose_play_sigma: np.ndarray  # (P,)
    pose_sag_per_kg: np.ndarray  # (P,)
    pose_offset: np.ndarray  # (P,)
    joint_zero: np.ndarray | float = 0.0  # (J,) or scalar: where the scale error vanishes
    seed: int = 0

    @classmethod
    def draw(
        cls, magnitudes: ErrorMagnitudes, n_joints: int, seed: int, joint_zero: np.ndarray | float = 0.0
    ) -> ErrorModel:
        """Draw one robot's systematic errors from ``seed`` (deterministic)."""
        rng = np.random.default_rng([seed, 0])
        n_pose = len(magnitudes.pose_play_sigma)
        return cls(
            scale=rng.normal(0.0, magnitudes.scale_sigma, n_joints),
            offset=rng.normal(0.0, magnitudes.offset_sigma, n_joints),
            backlash=magnitudes.backlash * rng.uniform(0.5, 1.5, n_joints),
            noise_sigma=magnitudes.noise_sigma,
            sag_per_kg=magnitudes.sag_per_kg * rng.uniform(0.5, 1.5, n_joints),
            pose_gain=rng.normal(0.0, magnitudes.pose_gain_sigma, (n_pose, n_pose)),
            pose_play_sigma=np.asarray(magnitudes.pose_play_sigma, dtype=float),
            pose_sag_per_kg=np.asarray(magnitudes.pose_sag_per_kg, dtype=float),
            pose_offset=rng.normal(0.0, 1.0, n_pose) * np.asarray(magnitudes.pose_offset_sigma, dtype=float),
            joint_zero=joint_zero,
            seed=seed,
        )

    @classmethod
    def ideal(cls, n_joints: int, n_pose: int) -> ErrorModel:
        """No error at all (the attained pose is the commanded one, up to step quantisation)."""
        zeros = np.zeros(n_joints)
        return cls(
            zeros,
            zeros,
            zeros,
            0.0,
            zeros,
            np.zeros((n_pose, n_pose)),
            np.zeros(n_pose),
            np.zeros(n_pose),
            np.zeros(n_pose),
        )

    def true_joints(
        self, commanded: np.ndarray, direction: np.ndarray, load_kg: float, rng: np.random.Generator
    ) -> np.ndarray:
        """Attained joint values, shape (J,), from commanded (J,) and last-motion directions (J,)."""
        noise = rng.normal(0.0, self.noise_sigma, commanded.shape) if self.noise_sigma else 0.0
        return (
            commanded
            + self.offset
            + self.scale * (commanded - self.joint_zero)
            - 0.5 * self.backlash * direction
            - self.sag_per_kg * load_kg
            + noise
        )

    def true_pose(
        self, pose: np.ndarray, reference_pose: np.ndarray, load_kg: float, rng: np.random.Generator
    ) -> np.ndarray:
        """Attained pose, shape (P,), from the forward kinematics of the attained joints."""
        play = rng.normal(0.0, 1.0, pose.shape) * self.pose_play_sigma
        return (
            pose + self.pose_offset + self.pose_gain @ (pose - reference_pose) + load_kg * self.pose_sag_per_kg + play
        )


@dataclass
class JointMemory:
    """Direction of the last motion of each joint (backlash depends on the approach direction)."""

    last: np.ndarray
    direction: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self.last = np.asarray(self.last, dtype=float)
        self.direction = np.zeros_like(self.last)

    def update(self, target: np.ndarray) -> np.ndarray:
        """Record a move to ``target``; a joint that does not move keeps its previous direction."""
        delta = np.sign(np.asarray(target, dtype=float) - self.last)
        self.direction = np.where(delta != 0, delta, self.direction)
        self.last = np.asarray(target, dtype=float)
        return self.direction
