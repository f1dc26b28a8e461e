"""motion: pure kinematics of the parallel robots that bench tests.

Arrays in, arrays out, shape ``(N, ...)`` (a single pose is N = 1); no I/O, no printing, no logging set-up.
Lengths are mm; inside each robot package angles are radians or degrees as its docstring says, and every robot is
also available in mm and degrees behind the common interface of :mod:`motion.model`.

Modules
-------
pkm5
    5-DOF PKM 2-R(Pa-IQ)RR, R(Pa-IQ)R with six lead-screw legs (000 dissertation).
delta4
    3-DOF 4-RSS modified delta robot with the laser-grid end-effector sensor.
prus3
    6-DOF 3-PRUS manipulator (stand-in geometry; the paper lost its dimensions).
model
    The structural ``RobotModel`` protocol every robot satisfies, and ``robot_models()``.
dual
    Forward-mode dual numbers: one kinematics code path gives values and exact Jacobians.
errors
    ``MotionInputError`` for malformed input.
"""
