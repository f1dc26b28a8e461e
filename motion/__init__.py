"""motion: pure kinematics of the parallel robots that bench tests.

Arrays in, arrays out, shape ``(N, ...)`` (a single pose is N = 1); no I/O, no printing, no logging set-up.
Lengths are mm; angles are radians inside the kinematics and degrees at the CLI and file boundaries.

Modules
-------
pkm5
    5-DOF PKM 2-R(Pa-IQ)RR, R(Pa-IQ)R with six lead-screw legs.
"""
