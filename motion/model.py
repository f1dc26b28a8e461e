"""The one structural interface every robot model satisfies, so protocols and the CLI treat robots alike.

A model names its pose fields and joints (with units and limits) and offers ``ik``, ``fk``, ``jacobian`` and
``workspace_samples`` on (N, ...) arrays in the public units (mm, degrees). Each robot package provides a
``MODEL`` instance (``motion.pkm5.model.MODEL``, ``motion.delta4.model.MODEL``, ``motion.prus3.model.MODEL``);
:func:`robot_models` lists those that are available.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["JointSpec", "ModelIK", "ModelFK", "RobotModel", "robot_models", "MODEL_MODULES", "column_conditioning"]

#: Packages that expose a ``model.MODEL``; the order is the listing order.
MODEL_MODULES = ("motion.pkm5.model", "motion.delta4.model", "motion.prus3.model")


@dataclass(frozen=True)
class JointSpec:
    """One joint: ``name`` with its unit in it (``servo1_deg``), ``unit``, limits ``low``..``high``, and whether
    it is ``actuated``."""

    name: str
    unit: str
    low: float
    high: float
    actuated: bool = True


@dataclass(frozen=True)
class ModelIK:
    """``joints`` (N, J) in the joints' units, ``reachable`` (N,), ``reason`` (N,) None or text."""

    joints: np.ndarray
    reachable: np.ndarray
    reason: np.ndarray


@dataclass(frozen=True)
class ModelFK:
    """``pose`` (N, P) in the pose fields' units, ``residual_mm`` (N,) consistency figure, ``ok`` (N,)."""

    pose: np.ndarray
    residual_mm: np.ndarray
    ok: np.ndarray


@runtime_checkable
class RobotModel(Protocol):
    """What the protocols and the CLI need from a robot's kinematics.

    Attributes
    ----------
    name : str
    pose_fields : tuple of str, e.g. ("x_mm", "y_mm", "z_mm")
    joints : tuple of JointSpec, the columns of ``ik(...).joints`` and of ``fk``'s input
    jacobian_joints : tuple of str, the rows of ``jacobian``: the joints that move the platform
    """

    name: str
    pose_fields: tuple[str, ...]
    joints: tuple[JointSpec, ...]
    jacobian_joints: tuple[str, ...]

    def ik(self, pose: ArrayLike) -> ModelIK:
        """Joint values for poses (N, P)."""

    def fk(self, joints: ArrayLike) -> ModelFK:
        """Poses for joint values (N, J)."""

    def jacobian(self, pose: ArrayLike) -> np.ndarray:
        """d(jacobian_joints)/d(pose fields), (N, len(jacobian_joints), P), in joint units per pose-field unit."""

    def workspace_samples(self, count: int, *, seed: int | None = 0) -> tuple[np.ndarray, np.ndarray]:
        """Uniform random poses (count, P) over the model's sampling box, and their reachability (count,)."""


def robot_models() -> dict[str, RobotModel]:
    """The available models by name."""
    models = (importlib.import_module(name).MODEL for name in MODEL_MODULES)
    return {model.name: model for model in models}


def column_conditioning(jacobian: ArrayLike, columns: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Smallest singular value and inverse condition number of each Jacobian restricted to its own columns.

    Parameters
    ----------
    jacobian : array_like, shape (N, J, P)
        Finite entries (``np.linalg.svd`` refuses NaN: what NaN means is the caller's choice).
    columns : array_like, shape (N, P) bool
        The pose columns each Jacobian is restricted to (a robot's motion mode, e.g. the pkm5's alpha or beta).

    Returns
    -------
    sigma_min, inverse_condition : ndarray (N,), ndarray (N,)
        sigma_min and sigma_min / sigma_max, in [0, 1]; a Jacobian without a non-zero singular value gives 0, as
        close to a singularity as it gets.

    Examples
    --------
    >>> jac = np.array([[[2.0, 0.0, 0.0], [0.0, 0.5, 0.0], [0.0, 0.0, 1e-9]], [[0.0, 0.0, 0.0]] * 3])
    >>> column_conditioning(jac, np.array([[True, True, False], [True, True, True]]))
    (array([0.5, 0. ]), array([0.25, 0.  ]))
    """
    jac = np.asarray(jacobian, dtype=float)
    sigma_min = np.zeros(len(jac))
    inverse_condition = np.zeros(len(jac))
    # one batched SVD per column pattern (the pkm5's translation, alpha and beta modes)
    patterns, group = np.unique(np.asarray(columns, bool), axis=0, return_inverse=True)
    for index, pattern in enumerate(patterns):
        rows = np.flatnonzero(group.ravel() == index)
        singular = np.linalg.svd(jac[rows][:, :, pattern], compute_uv=False)
        sigma_min[rows] = singular[:, -1]
        with np.errstate(divide="ignore", invalid="ignore"):
            inverse_condition[rows] = np.where(singular[:, 0] > 0, singular[:, -1] / singular[:, 0], 0.0)
    return sigma_min, inverse_condition
