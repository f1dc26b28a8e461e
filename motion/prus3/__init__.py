"""motion.prus3: kinematics of the 6-actuator 3-PRUS spatial parallel manipulator (pure numpy).

Source: Thomas, Joy, Sudheer, "Kinematic and Dynamic Analysis of a 3-PRUS Spatial Parallel Manipulator",
Chin. J. Mech. Eng. 33 (2020), through ``shared/reference/prus3.md``. The paper lost every link dimension;
:data:`STAND_IN` holds the reference's round stand-in values (a = 600, b = 75, c = 100, stroke 0-1200 mm).

What is and is not well defined
-------------------------------
* Poses are (N, 6): tip x, y, z (mm) in {O2} and alpha, beta, gamma (deg), R = Rz(gamma) Ry(beta) Rx(alpha)
  (the convention of the paper's Eq. 14; its Eq. 12 matrix is not a rotation, erratum E5).
* Slider IK is closed form with two branches per leg (8 assembly modes).
* The actuated revolute x2 is redundant with the passive universal joint (x3, x4): the three axes meet in one
  point, so x2 only spins the link. It is returned through a convention (default ``clip``: x2 = clip(phi,
  +-L2)); reachability uses the convention-free existence test.
* Consequently the six actuators do not determine the pose: with them locked the platform keeps 3 DoF
  (reference §2, TV-6). FK needs complete leg joint sets (:func:`forward_kinematics`);
  :func:`actuator_residual_mm` checks a measured pose against slider readings.
* The slider-rate Jacobian is 3 x 6 (:func:`slider_jacobian`); the paper's 6 x 6 cannot be rebuilt.
"""

from motion.prus3.geometry import STAND_IN, Geometry, PoseFit, corners_mm, pose_from_corners, rotation_matrix
from motion.prus3.jacobian import SliderJacobian, slider_jacobian
from motion.prus3.kinematics import IKResult, actuator_residual_mm, forward_kinematics, inverse_kinematics
from motion.prus3.revolute import CONVENTIONS
from motion.prus3.trajectory import STAND_IN_ORIGIN_MM, Trajectory, paper_trajectory
from motion.prus3.workspace import WorkspaceVolume, workspace_samples, workspace_volume, workspace_volume_quadrature

__all__ = [
    "Geometry",
    "STAND_IN",
    "PoseFit",
    "corners_mm",
    "pose_from_corners",
    "rotation_matrix",
    "IKResult",
    "inverse_kinematics",
    "forward_kinematics",
    "actuator_residual_mm",
    "CONVENTIONS",
    "SliderJacobian",
    "slider_jacobian",
    "Trajectory",
    "STAND_IN_ORIGIN_MM",
    "paper_trajectory",
    "WorkspaceVolume",
    "workspace_samples",
    "workspace_volume",
    "workspace_volume_quadrature",
]
