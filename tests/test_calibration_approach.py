"""Poses approached from below (``approach_from_below_mm`` of the ISO 9283 pose protocol): every pkm5 leg extends
into every pose of the calibration and validation protocols, so each leg's backlash is taken up on one side at
every arrival (docs/calibration.md, "Backlash")."""

import tomllib
from pathlib import Path

import numpy as np
import pytest

from bench.errors import ConfigError
from bench.protocols.iso9283 import PoseAccuracy
from bench.steps import Capture, Move
from motion import pkm5

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def _protocol(name: str) -> PoseAccuracy:
    settings = tomllib.loads((EXAMPLES / name).read_text())
    settings.pop("protocol")
    return PoseAccuracy(**settings)


def _first_cycle_moves(protocol: PoseAccuracy) -> list[Move]:
    moves, plan = [], protocol.steps()
    step = next(plan)
    while not (isinstance(step, Capture) and step.pose == list(protocol.test_poses())[-1]):
        if isinstance(step, Move):
            moves.append(step)
        step = plan.send({"x_mm": 0.0}) if isinstance(step, Capture) else next(plan)
    return moves


def _lengths(poses_deg) -> np.ndarray:
    rad = np.array(poses_deg, dtype=float)
    rad[:, 3:] = np.radians(rad[:, 3:])
    return pkm5.inverse_kinematics(rad).lengths_mm


@pytest.mark.parametrize("name", ["kinematic_calibration.toml", "kinematic_validation.toml"])
def test_every_leg_extends_into_every_pose_of_the_examples(name):
    protocol = _protocol(name)
    assert protocol.approach_from_below_mm == 1.0
    moves = _first_cycle_moves(protocol)
    poses = protocol.test_poses()
    assert [m.label for m in moves] == [label for pose in poses for label in (f"{pose}/below", pose)]
    below, at = [m.target for m in moves[::2]], [m.target for m in moves[1::2]]
    drops = np.array(at)[:, 2] - np.array(below)[:, 2]
    assert np.array(below)[:, [0, 1, 3, 4]] == pytest.approx(np.array(at)[:, [0, 1, 3, 4]])
    extension = _lengths(at) - _lengths(below)
    # the last move lengthens every leg by more than the documented robot's largest backlash (0.15 mm in the
    # simulator's draw) at every pose but C11, whose legs 3 and 4 stand 0.14 mm above their window
    assert extension.min() > 0
    if name == "kinematic_calibration.toml":
        assert protocol.resolved()["approach_mm"]["C11"] == pytest.approx(0.1)
        assert sorted(set(np.round(drops, 6))) == [0.1, 0.5, 1.0]
        assert (extension.min(axis=1) > 0.15).sum() == len(poses) - 1
    else:
        assert drops == pytest.approx(1.0) and extension.min() > 0.5


def test_a_pose_without_room_below_is_refused_naming_it():
    # leg 4 of C11 stands 0.14 mm above its shortest: 0.1 mm below passes, a pose 0.05 mm lower has no room left
    c11 = [111.31, 90.04, 302.9 - 0.13, -7.42, 0.0]
    with pytest.raises(ConfigError, match=r"approach_from_below_mm = 1: poses LOW cannot be approached from below"):
        PoseAccuracy(poses={"OK": [110.0, 0.0, 320.0, 0.0, 0.0], "LOW": c11}, approach_from_below_mm=1.0, cycles=2)


def test_a_direct_approach_makes_no_extra_move():
    protocol = PoseAccuracy(poses={"A": [110.0, 0.0, 320.0], "B": [120.0, 5.0, 310.0]}, cycles=2)
    assert [m.label for m in _first_cycle_moves(protocol)] == ["A", "B"]
    assert "approach_mm" not in protocol.resolved()


def test_the_calibration_records_how_its_poses_were_approached(tmp_path_factory):
    # the ideal simulator's calibration run of examples/kinematic_calibration.toml (2 cycles, as written otherwise)
    from calibrated_pkm5 import calibrated_runs

    runs = calibrated_runs(tmp_path_factory)
    assert runs.calibration["approach_from_below_mm"] == 1.0
