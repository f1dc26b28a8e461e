#!/usr/bin/env bash
# The main job of bench, run by `./dev demo`: kinematics examples of the 5-DOF PKM (the simulated campaign joins
# here when the campaign runner lands).
set -euo pipefail
echo "== IK: the home pose of the PKM (every leg at 5 mm stroke)" >&2
bench kin ik pkm5 88.649 0 300.937
echo "== IK with a roll of 10 deg (alpha poses live on the plane x = 111.31 mm)" >&2
bench kin ik pkm5 111.31 -20 310 --alpha 10 --json
echo "== FK: the leg lengths at full retraction (001 Table I) give the pose printed in 001 §IV.A" >&2
bench kin fk pkm5 184 184 184 184 192 192
echo "== Workspace at constant orientation: hit-or-miss volume and the dissertation's convex hull" >&2
bench kin workspace pkm5 --samples 200000 --seed 0
