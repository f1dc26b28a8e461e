"""Kinematics of the 5-DOF PKM 2-R(Pa-IQ)RR, R(Pa-IQ)R (six lead-screw legs in three coplanar pairs).

Spec: ``shared/reference/pkm5.md``; the dissertation 000_1cca5531533552b2.txt is authoritative.

Poses are arrays (N, 5): x, y, z [mm], alpha (roll about x), beta (pitch about y) [rad]. Leg lengths are |BC| in
mm, shape (N, 6). Three motion modes as in the documents: translation, translation + alpha (on the plane
x = 111.31 mm), translation + beta; alpha and beta together are refused (parasitic gamma is not modelled).
"""

from motion.pkm5.fk import NEUTRAL_POSE, FKResult, detect_mode, forward_kinematics
from motion.pkm5.geometry import DEFAULT_GEOMETRY, Geometry, lengths_to_steps, steps_to_lengths
from motion.pkm5.ik import Failure, IKResult, bracket_vectors, inverse_kinematics
from motion.pkm5.jacobian import SingularityProximity, jacobian, singularity_proximity
from motion.pkm5.nr import NRResult, forward_kinematics_nr
from motion.pkm5.workspace import WORKSPACE_KINDS, WorkspaceEstimate, estimate_workspace, sample_reachable

__all__ = [
    "DEFAULT_GEOMETRY",
    "Geometry",
    "lengths_to_steps",
    "steps_to_lengths",
    "Failure",
    "IKResult",
    "bracket_vectors",
    "inverse_kinematics",
    "FKResult",
    "NEUTRAL_POSE",
    "detect_mode",
    "forward_kinematics",
    "SingularityProximity",
    "jacobian",
    "singularity_proximity",
    "NRResult",
    "forward_kinematics_nr",
    "WORKSPACE_KINDS",
    "WorkspaceEstimate",
    "estimate_workspace",
    "sample_reachable",
]
