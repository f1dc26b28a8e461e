"""Errors raised by motion/ for malformed input (wrong shape, wrong mode); never for an unreachable pose,
which is reported per pose in the results instead."""


class MotionInputError(ValueError):
    """An argument to a kinematics function has the wrong shape, range or combination."""
