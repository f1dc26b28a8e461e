"""The runner's own pre-flight: by the geometry the rig's robot commands by, in one walk of the plan, and no target
commanded that was not proved reachable (bench.protocols.runner, bench.protocols.plan)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from test_protocols import Answers, BiasedInstrument, RecordingRobot

from bench.errors import ConfigError, UnreachableTarget
from bench.protocols import Capture, Checkpoint, Move, Rig, Runner, preflight
from bench.protocols.base import PROTOCOLS, Protocol
from bench.protocols.iterative import IterativeCorrection
from bench.protocols.kinematics import robot_model
from bench.steps import commanded_values
from bench.store import Store
from motion import pkm5

NEAR = (110.0, 0.0, 320.0)  # legs 1-4 213.6 mm, 5-6 215.0 mm
HIGH = (110.0, 0.0, 340.0)  # legs 1-4 232.0 mm, 5-6 235.0 mm: inside the documented 244/252 mm windows
#: a robot whose legs end 15 mm short of the documented window (e.g. a calibrated or a rebuilt one)
SHORT_LEGS = replace(pkm5.DEFAULT_GEOMETRY, leg_max_mm=tuple(v - 15.0 for v in pkm5.DEFAULT_GEOMETRY.leg_max_mm))


#: one entry per generation of a _Counted plan (a resumed run's protocol is a new instance, made from its config)
WALKS: list[str] = []


class _Counted(Protocol):
    """Five moves to NEAR, each followed by a capture and a checkpoint, then one to ``last``; each generation of its
    plan is counted in :data:`WALKS`."""

    name = "test_counted"
    version = "1"

    def __init__(self, last=NEAR, **kwargs) -> None:
        super().__init__(**kwargs)
        self.last = last

    def steps(self):
        WALKS.append("steps")
        for cycle in range(1, 6):
            yield Move(NEAR, 100.0, f"P{cycle}")
            yield Capture("P", cycle, commanded=commanded_values(NEAR))
            yield Checkpoint(f"cycle {cycle}")
        yield Move(self.last, 100.0, "LAST")

    def final_steps(self):
        yield from ()


class _WalksAtFirstMove(RecordingRobot):
    """Records how often a plan had been generated when its first move was commanded (:data:`WALKS`)."""

    def __init__(self, geometry=None, fail_after=None) -> None:
        super().__init__(fail_after)
        self.geometry, self.walks_at_first_move = geometry, None
        WALKS.clear()

    def move_to(self, target, *, velocity_pct):
        if self.walks_at_first_move is None:
            self.walks_at_first_move = len(WALKS)
        super().move_to(target, velocity_pct=velocity_pct)


def _rig(robot, instrument=None):
    return Rig(robot, instrument or BiasedInstrument(), Answers(), speed_factor=1e6, sleep=lambda s: None)


@pytest.fixture()
def store(tmp_path):
    with Store(tmp_path / "bench.db") as s:
        yield s


def test_the_geometry_the_reach_is_checked_by_decides():
    """The oracle of the next test: HIGH is inside the documented leg windows and outside SHORT_LEGS'."""
    documented = robot_model("pkm5").check(np.array([HIGH + (0.0, 0.0)]))
    short = replace(robot_model("pkm5"), geometry=SHORT_LEGS).check(np.array([HIGH + (0.0, 0.0)]))
    assert documented.reachable.tolist() == [True] and short.reachable.tolist() == [False]
    assert "leg" in short.reason[0]


def test_a_target_out_of_the_rigs_reach_late_in_the_plan_moves_nothing(store):
    protocol = _Counted(last=HIGH)
    assert preflight(protocol).ok  # by the documented geometry the whole plan is reachable
    robot = _WalksAtFirstMove(geometry=SHORT_LEGS)
    with pytest.raises(UnreachableTarget, match=r"target LAST \(x 110.00 mm, y 0.00 mm, z 340.00 mm.*not reachable"):
        Runner(_rig(robot), store).run(protocol)
    assert robot.log == []  # not one move, not even a stop: nothing was started
    assert store.runs() == []  # and nothing stored


def test_the_plan_is_walked_once_before_the_first_move(store):
    robot = _WalksAtFirstMove()
    result = Runner(_rig(robot), store).run(_Counted())
    assert result.exit_status == "completed" and result.samples == 5
    # the pre-flight's walk (which also counted the samples), then the run's own, which commands the move
    assert robot.walks_at_first_move == 2 and len(WALKS) == 2


def test_a_resume_walks_the_plan_once_before_its_first_move(store):
    failed = Runner(_rig(_WalksAtFirstMove(fail_after=2)), store).run(_Counted())
    assert failed.exit_status == "failed" and failed.samples == 2  # the third move failed
    PROTOCOLS[_Counted.name] = _Counted
    try:
        robot = _WalksAtFirstMove()
        resumed = Runner(_rig(robot), store).resume_run(failed.run_id)
    finally:
        del PROTOCOLS[_Counted.name]
    assert resumed.exit_status == "completed" and resumed.samples == 5
    # one walk found the resume point, counted the samples and proved the targets; then the run's own
    assert robot.walks_at_first_move == 2 and len(WALKS) == 2
    assert len([entry for entry in robot.log if entry[0] == "move"]) == 4  # from the checkpoint of cycle 2 on


def test_a_resume_uses_the_pre_flight_made_with_its_stored_samples_and_no_other(store):
    from bench.protocols.resume import stored_replies

    PROTOCOLS[_Counted.name] = _Counted
    try:
        for with_stored, walks in ((True, 2), (False, 3)):
            failed = Runner(_rig(_WalksAtFirstMove(fail_after=2)), store).run(_Counted())
            robot = _WalksAtFirstMove()
            # made without the stored samples its resume point would be wrong: the runner walks the plan itself
            early = preflight(_Counted(), stored=stored_replies(store, failed.run_id) if with_stored else None)
            resumed = Runner(_rig(robot), store).resume_run(failed.run_id, plan=early)
            assert resumed.exit_status == "completed" and resumed.samples == 5
            assert robot.walks_at_first_move == walks
            assert len([entry for entry in robot.log if entry[0] == "move"]) == 4  # from cycle 2's checkpoint
    finally:
        del PROTOCOLS[_Counted.name]


def test_a_target_the_plan_chooses_during_the_run_is_checked_before_it_is_commanded(store):
    """An adaptive plan (the iterative correction) moves to corrected commands no dry run can foresee: each is
    checked alone by the rig's model before it is commanded, and one out of reach fails the run unmoved."""

    class FarOff(BiasedInstrument):  # reads 40 mm above the command: the correction goes 40 mm down
        def measure(self, capture):
            m = super().measure(capture)
            return type(m)({**m.values, "z_mm": m.values["z_mm"] + 40.0}, m.raw)

    corrected = (110.0, 0.0, 320.0 - 40.125)  # c - (m - T), with the instrument's +0.125 mm z bias
    assert not robot_model("pkm5").check(np.array([corrected + (0.0, 0.0)])).reachable[0]
    robot = RecordingRobot()
    result = Runner(_rig(robot, FarOff()), store).run(IterativeCorrection(poses={"T1": NEAR}, settle_s=0.0))
    assert result.exit_status == "failed" and isinstance(result.exception, UnreachableTarget)
    assert "the plan chose it during the run" in result.reason
    assert [entry[1] for entry in robot.log if entry[0] == "move"][:2] == [NEAR]  # the first command only, then home


def test_a_rig_of_another_robot_is_refused_before_anything_is_stored(store):
    robot = RecordingRobot()
    robot.kind = "delta4"
    with pytest.raises(ConfigError, match="robot = 'pkm5', but this rig's robot is 'delta4'"):
        Runner(_rig(robot), store).run(_Counted())
    assert robot.log == [] and store.runs() == []


def test_one_walk_counts_samples_and_readings_and_finds_where_a_resume_acts_from():
    from bench.protocols import Prompt

    class WithReadings(_Counted):
        def steps(self):
            yield from super().steps()
            yield Prompt("depth", field="depth_mm", unit="mm", pose="P", cycle=1, kind="depth")

    # steps per cycle: Move, Capture, Checkpoint (indices 3k, 3k + 1, 3k + 2); cycles 1 and 2 stored
    summary = preflight(WithReadings(), stored={1: {"x_mm": 0.0}, 4: {"x_mm": 0.0}})
    assert (summary.samples, summary.readings, summary.resume_at) == (6, 1, 5)  # from cycle 2's checkpoint
    assert preflight(WithReadings()).resume_at == 0  # nothing stored: from the start
    stored = {1: {}, 4: {}, 7: {}, 10: {}, 13: {}, 16: 1.0}  # every sample stored (the prompt is step 16)
    assert preflight(WithReadings(), stored=stored).resume_at is None


def test_a_pre_flight_made_before_the_rig_opened_is_checked_again_by_its_geometry_without_a_walk(store):
    """``bench run`` walks the plan before it opens the rig (its capabilities); the runner then checks that walk's
    targets by the rig's own geometry instead of walking the plan again."""
    protocol = _Counted(last=HIGH)
    robot = _WalksAtFirstMove(geometry=SHORT_LEGS)
    early = preflight(protocol)
    with pytest.raises(UnreachableTarget, match=r"target LAST \(x 110.00 mm, y 0.00 mm, z 340.00 mm.*not reachable"):
        Runner(_rig(robot), store).run(protocol, plan=early)
    assert len(WALKS) == 1 and robot.log == [] and store.runs() == []  # the early walk only; nothing moved

    robot = _WalksAtFirstMove()
    early = preflight(protocol)
    result = Runner(_rig(robot), store).run(protocol, plan=early)
    assert result.exit_status == "completed" and result.samples == 5
    assert robot.walks_at_first_move == 2 and len(WALKS) == 2  # the early walk, then the run's own
