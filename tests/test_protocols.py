"""bench.protocols: parameters, TOML loading, step sequences, pre-flight, and the runner's states and resume."""

from __future__ import annotations

import logging
import math
import threading

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from runner_support import RunInThread, StandInMover, wait_until

from bench.errors import ConfigError, PromptWithdrawn, UnreachableTarget
from bench.protocols import (
    Capture,
    Checkpoint,
    Measurement,
    Move,
    Prompt,
    Rig,
    Runner,
    Settle,
    TransitionError,
    load_protocol,
    preflight,
    summarize,
)
from bench.protocols.iso9283 import (
    DistanceAccuracy,
    Drift,
    MultiDirectional,
    PoseAccuracy,
    cube_poses,
    fit_cube_side,
)
from bench.protocols.kinematics import robot_model
from bench.protocols.parameters import MAX_COUNT, MAX_PLAN_REPEATS
from bench.protocols.plan import iterate
from bench.protocols.runner import TRANSITIONS, RunState
from bench.store import Store, tidy_table

BIAS = np.array([0.5, -0.25, 0.125])


class RecordingRobot(StandInMover):
    def __init__(self, fail_after: int | None = None):
        self.log: list[tuple] = []
        self.fail_after = fail_after
        self.stopped_from: list[str] = []  # the thread each stop() came from

    def move_to(self, target, *, velocity_pct):
        if self.fail_after is not None and len([e for e in self.log if e[0] == "move"]) >= self.fail_after:
            raise OSError("port vanished")
        self.log.append(("move", tuple(target), velocity_pct))

    def stop(self):
        self.log.append(("stop",))
        self.stopped_from.append(threading.current_thread().name)

    def shutdown(self):
        self.log.append(("shutdown",))

    def settings(self):
        return {"driver": "recording"}


class BiasedInstrument:
    """Measures the last commanded position plus a fixed bias (exact AP, RP = 0)."""

    def measure(self, capture: Capture) -> Measurement:
        cmd = np.array([capture.commanded[k] for k in ("cmd_x_mm", "cmd_y_mm", "cmd_z_mm")])
        x, y, z = cmd + BIAS
        return Measurement({"x_mm": x, "y_mm": y, "z_mm": z}, raw={"truth": list(cmd)})

    def settings(self):
        return {"instrument": "biased"}


class Answers:
    def __init__(self):
        self.asked = []

    def ask(self, prompt):
        self.asked.append(prompt)
        return None if prompt.field is None else 1.25


def _rig(robot=None):
    return Rig(robot or RecordingRobot(), BiasedInstrument(), Answers(), speed_factor=1e6, sleep=lambda s: None)


@pytest.fixture()
def store(tmp_path):
    with Store(tmp_path / "bench.db") as s:
        yield s


def _small(**kw):
    return PoseAccuracy(**{"cycles": 3, "velocities_pct": [100, 10], "settle_s": 0.5, **kw})


# ---- parameters and TOML ---------------------------------------------------------------------------------------


def test_toml_error_names_file_field_value_and_expectation(tmp_path):
    path = tmp_path / "pose_test.toml"
    path.write_text('protocol = "iso9283_pose"\ncycles = 0\n')
    with pytest.raises(ConfigError, match=r"^pose_test.toml: cycles = 0, expected an integer in \[2, 100000\]$"):
        load_protocol(path)


@pytest.mark.parametrize("value", ['["iso9283_pose"]', '{ name = "iso9283_pose" }', "3"])
def test_protocol_name_that_is_no_string_is_one_line(tmp_path, value):
    path = tmp_path / "pose_test.toml"
    path.write_text(f"protocol = {value}\n")
    with pytest.raises(ConfigError, match=r"^pose_test.toml: protocol = .*, expected one of .*iso9283_pose"):
        load_protocol(path)


def test_unknown_key_is_refused(tmp_path):
    path = tmp_path / "pose_test.toml"
    path.write_text('protocol = "iso9283_pose"\ncycels = 3\n')
    with pytest.raises(ConfigError, match="pose_test.toml: unknown key 'cycels', expected one of"):
        load_protocol(path)


@pytest.mark.parametrize(
    "text, message",
    [
        ('settle_s = "2 s"', None),
        ('settle_s = "2 mm"', r"settle_s = '2 mm', expected a number in \[0, 600\] s"),
        (
            "velocities_pct = [100, 150]",
            (
                r"velocities_pct = \[100, 150\], expected a non-empty list of numbers in "
                r"\[0.1, 100\]%"
            ),
        ),
        ('robot = "scara"', "robot = 'scara', expected one of 'pkm5', 'delta4'"),
        ("cycles = 2.5", r"cycles = 2.5, expected an integer in \[2, 100000\]"),
        ("cycles = 100001", r"cycles = 100001, expected an integer in \[2, 100000\]"),  # absurd sizes: refused at once
        ("cycles = 1e20", r"cycles = 1e\+20, expected an integer in \[2, 100000\]"),
        ("cycles = 1e308", r"cycles = 1e\+308, expected an integer in \[2, 100000\]"),
    ],
)
def test_parameter_conversion(tmp_path, text, message):
    path = tmp_path / "p.toml"
    path.write_text(f'protocol = "iso9283_pose"\n{text}\n')
    if message is None:
        assert load_protocol(path).settle_s == 2.0
    else:
        with pytest.raises(ConfigError, match=message):
            load_protocol(path)


@settings(max_examples=40, deadline=None)
@given(
    st.integers(min_value=2, max_value=40),
    st.lists(st.sampled_from([100.0, 50.0, 10.0]), min_size=1, max_size=3, unique=True),
)
def test_a_pose_plan_captures_every_pose_once_per_cycle_and_velocity(cycles, velocities):
    """ISO 9283 7.2.1: each of P1-P5 measured `cycles` times at each velocity, in cycles 1..n visiting P1, P5, P4,
    P3, P2 (the standard's order), velocity after velocity in the order given."""
    protocol = PoseAccuracy(cycles=cycles, velocities_pct=velocities, cube_side_mm=20)
    captures = [step for step in protocol.steps() if isinstance(step, Capture)]
    assert len(captures) == 5 * cycles * len(velocities)
    for block, velocity in enumerate(velocities):
        visits = captures[block * 5 * cycles : (block + 1) * 5 * cycles]
        assert {step.conditions["velocity_pct"] for step in visits} == {velocity}
        assert [(step.pose, step.cycle) for step in visits] == [
            (pose, cycle) for cycle in range(1, cycles + 1) for pose in ("P1", "P5", "P4", "P3", "P2")
        ]


@given(st.one_of(st.integers(min_value=MAX_COUNT + 1), st.floats(min_value=MAX_COUNT + 1, allow_infinity=True)))
def test_any_absurd_cycle_count_is_refused_before_a_plan_exists(cycles):
    with pytest.raises(ConfigError, match=r"cycles = .*, expected an integer in \[2, 100000\]$"):
        PoseAccuracy(cycles=cycles, cube_side_mm=20)


@settings(max_examples=30, deadline=None)
@given(
    cycles=st.integers(min_value=2, max_value=MAX_COUNT),
    velocities=st.lists(st.sampled_from([100.0, 50.0, 10.0]), min_size=1, max_size=2000),
    loads=st.lists(st.just(0.0), min_size=1, max_size=2000),
)
@example(cycles=MAX_COUNT, velocities=[50.0] * 1000, loads=[0.0])
@example(cycles=MAX_COUNT, velocities=[100.0, 50.0, 10.0], loads=[0.0, 0.0, 0.0])  # 9 x 10^5: built
def test_a_plan_whose_sizes_multiply_beyond_the_bound_is_refused_before_it_exists(cycles, velocities, loads):
    """Each size within its bound, their product beyond MAX_PLAN_REPEATS (100 000 cycles x 1 000 velocities: hours
    of dry run before) is one line naming each factor; within it the protocol is built (its plan not walked)."""
    repeats = cycles * len(velocities) * len(loads)
    values = dict(cycles=cycles, velocities_pct=velocities, loads_kg=loads, cube_side_mm=20)
    if repeats <= MAX_PLAN_REPEATS:
        assert PoseAccuracy(**values).cycles == cycles
        return
    with pytest.raises(ConfigError) as refused:
        PoseAccuracy(**values)
    assert str(refused.value) == (
        "parameters: a plan of "
        + " x ".join(
            f"{key} {size:,}"
            for key, size in (("cycles", cycles), ("velocities_pct", len(velocities)), ("loads_kg", len(loads)))
            if size > 1
        )
        + f" = {repeats:,} repetitions, expected at most {MAX_PLAN_REPEATS:,} (lower one of them)"
    )


# ---- cube and steps ----------------------------------------------------------------------------------------------


def test_cube_poses_follow_iso_geometry():
    poses = cube_poses((100, 0, 300), 50.0)
    p2, p4 = np.array(poses["P2"]), np.array(poses["P4"])
    assert np.linalg.norm(p2 - p4) == pytest.approx(0.8 * 50 * np.sqrt(3))  # D_c = 0.8 L sqrt(3), iso9283.md §5.3
    assert np.mean([poses[p] for p in ("P2", "P3", "P4", "P5")], axis=0) == pytest.approx(poses["P1"])


def test_fitted_cube_is_reachable_and_maximal():
    side = fit_cube_side("pkm5", (110, 0, 320))
    assert 30 < side < 60
    assert fit_cube_side("pkm5", (110, 0, 320), max_side_mm=side) == side
    with pytest.raises(UnreachableTarget):
        preflight(PoseAccuracy(cube_centre_mm=[110, 0, 320], cube_side_mm=side * 1.6, cycles=2))


def test_pose_protocol_step_sequence():
    steps = list(iterate(_small(velocities_pct=[50]), final=False))
    first_cycle = steps[:16]
    assert [type(s) for s in first_cycle] == [Move, Settle, Capture] * 5 + [Checkpoint]
    assert [s.label for s in first_cycle if isinstance(s, Move)] == ["P1", "P5", "P4", "P3", "P2"]
    assert all(s.velocity_pct == 50 for s in steps if isinstance(s, Move))
    captures = [s for s in steps if isinstance(s, Capture)]
    assert len(captures) == 15 and [c.cycle for c in captures[::5]] == [1, 2, 3]


def test_dry_run_counts_and_estimate():
    summary = summarize(_small())
    assert summary.counts == {"moves": 31, "settles": 30, "captures": 30, "checkpoints": 6}
    assert summary.ok and summary.settle_s == 15.0
    assert summary.move_s > 0 and "estimated duration" in summary.lines()[1]


def test_unreachable_target_is_refused_before_any_motion(tmp_path, store):
    path = tmp_path / "bad.toml"
    path.write_text('protocol = "iso9283_pose"\ncycles = 2\n[poses]\nP1 = [110, 0, 320]\nFAR = [300, 0, 300]\n')
    robot = RecordingRobot()
    with pytest.raises(
        UnreachableTarget,
        match=r"bad.toml: target FAR \(x 300.00 mm, y 0.00 mm, z 300.00 mm.*"
        r"not reachable: leg 1 length 316.729 mm outside \(184, 244\) mm",
    ):
        Runner(_rig(robot), store).run(load_protocol(path))
    assert robot.log == [] and store.runs() == []


# ---- runner ------------------------------------------------------------------------------------------------------


def test_completed_run_stores_every_sample_with_exact_bias(store):
    robot = RecordingRobot()
    result = Runner(_rig(robot), store).run(_small())
    assert (result.exit_status, result.samples) == ("completed", 30)
    table = tidy_table(store, result.run_id)
    error = table[["x_mm", "y_mm", "z_mm"]].to_numpy() - table[["cmd_x_mm", "cmd_y_mm", "cmd_z_mm"]].to_numpy()
    assert error == pytest.approx(np.tile(BIAS, (30, 1)))
    assert sorted(table["velocity_pct"].unique()) == [10.0, 100.0]
    assert robot.log[-2][1] == pytest.approx((88.649, 0.0, 300.937, 0.0, 0.0))  # clean-up: home
    assert robot.log[-1] == ("shutdown",)
    run = store.run(result.run_id)
    assert run.status == "completed" and run.config["cycles"] == 3 and run.config["protocol"] == "iso9283_pose"


def test_illegal_transitions_raise():
    runner = Runner(_rig(), Store(":memory:"))
    with pytest.raises(TransitionError, match="cannot resume while idle"):
        runner.resume()
    with pytest.raises(TransitionError, match="cannot go from idle to stopping"):
        runner.stop()
    with pytest.raises(TransitionError, match="cannot pause while idle"):
        runner.request_pause()
    assert RunState.FINISHED not in TRANSITIONS[RunState.IDLE]


def _pausing(action):
    def on_pause(runner):
        getattr(runner, action)()

    return on_pause


@pytest.mark.parametrize(
    "action, status, home, stop_sent",
    [
        ("resume", "completed", True, False),
        ("stop", "aborted", True, False),
        ("abort", "aborted", True, True),
        ("halt", "aborted", False, True),
    ],
)
def test_pause_at_checkpoint_then_decide(store, action, status, home, stop_sent):
    robot = RecordingRobot()
    runner = Runner(_rig(robot), store, on_pause=_pausing(action))
    instrument = runner.rig.instrument
    measure = instrument.measure

    def measure_and_request_pause(capture):
        if capture.cycle == 1 and capture.pose == "P3" and runner.state is RunState.RUNNING:
            runner.request_pause()
        return measure(capture)

    instrument.measure = measure_and_request_pause
    result = runner.run(_small())
    assert result.exit_status == status
    assert result.samples == (30 if action == "resume" else 5)  # paused only after the whole cycle 1
    assert (robot.log[-2][0] == "move" and robot.log[-2][1][0] == 88.649) == home
    assert (("stop",) in robot.log) == stop_sent
    assert robot.log[-1] == ("shutdown",)


def test_failure_mid_run_is_stored_with_reason_and_robot_stopped(store):
    robot = RecordingRobot(fail_after=7)
    result = Runner(_rig(robot), store).run(_small())
    assert result.exit_status == "failed" and result.samples == 7
    assert store.run(result.run_id).reason == "OSError: port vanished"
    assert robot.log[-2:] == [("stop",), ("shutdown",)]


def test_resume_gives_exactly_the_expected_samples(store):
    failed = Runner(_rig(RecordingRobot(fail_after=8)), store).run(_small())
    assert failed.samples == 8
    robot = RecordingRobot()
    resumed = Runner(_rig(robot), store).resume_run(failed.run_id)
    assert (resumed.exit_status, resumed.samples) == ("completed", 30)
    moves = [e[2:] and e[1] for e in robot.log if e[0] == "move"]
    # restarts at the checkpoint closing cycle 1: cycle 2 again from P1 (P1..P3 of cycle 2 are already stored)
    assert len(moves) == 30 - 5 + 1
    table = tidy_table(store, failed.run_id)
    assert len(table) == 30 and table.groupby(["velocity_pct", "pose"]).size().eq(3).all()
    with pytest.raises(ConfigError, match="already completed"):
        Runner(_rig(), store).resume_run(failed.run_id)


def test_resume_refuses_changed_calibration(store):
    failed = Runner(_rig(RecordingRobot(fail_after=3)), store).run(_small())
    rig = _rig()
    rig.calibration_ids = (7,)
    with pytest.raises(ConfigError, match=r"calibrations in force \[7\] differ from the run's \[\]"):
        Runner(rig, store).resume_run(failed.run_id)


def test_prompts_store_readings_and_loads_ask_confirmation(store):
    protocol = _two_loads()
    steps = list(iterate(protocol, final=False))
    prompts = [s for s in steps if isinstance(s, Prompt)]
    assert [p.conditions for p in prompts] == [{"load_kg": 2.5}]
    assert [s.label for s in steps if isinstance(s, Move)][:2] == ["P4", "P2"]
    result = Runner(_rig(), store).run(protocol)
    assert result.samples == 8


def _payload_prompts(protocol):
    """(text, load_kg) of every confirmation in the plan, clean-up included, and the label of the move before it."""
    steps, out = list(iterate(protocol)), []
    for i, step in enumerate(steps):
        if isinstance(step, Prompt):
            before = next((s.label for s in reversed(steps[:i]) if isinstance(s, Move)), None)
            out.append((step.text, step.conditions["load_kg"], before))
    return out


def _two_loads(loads=(0, 2.5)):
    """A short distance run at two loads (two poses, two cycles each)."""
    return DistanceAccuracy(cycles=2, velocities_pct=[100], loads_kg=list(loads), settle_s=0)


MOUNT_25 = "Mount a payload of 2.5 kg on the end effector, then confirm"
REMOVE_25 = "Remove the 2.5 kg payload from the end effector, then confirm"


class _PayloadOperator(Answers):
    """Answers confirmations, noting the robot's last move at each (where the operator is asked); withdraws the
    ones whose text starts with ``withdraw``; asks ``runner`` to stop (at its next checkpoint) on ``stop_on``."""

    def __init__(self, robot, withdraw: str | None = None, stop_on: str | None = None):
        super().__init__()
        self.robot, self.withdraw, self.stop_on, self.at, self.runner = robot, withdraw, stop_on, [], None

    def ask(self, prompt):
        moves = [entry for entry in self.robot.log if entry[0] == "move"]
        self.at.append(moves[-1][1] if moves else None)
        if self.withdraw and prompt.text.startswith(self.withdraw):
            self.asked.append(prompt)
            raise PromptWithdrawn("the window closed")
        if prompt.text == self.stop_on:
            self.runner.stop()
        return super().ask(prompt)


def _payload_rig(**operator):
    rig = _rig()
    rig.operator = _PayloadOperator(rig.robot, **operator)
    return rig


def test_a_payload_still_on_after_the_clean_up_is_asked_to_come_off_at_home(store):
    protocol = _two_loads()
    assert _payload_prompts(protocol) == [(MOUNT_25, 2.5, "P2")]
    assert _payload_prompts(protocol) == [(MOUNT_25, 2.5, "P2")]  # walked again (counted, pre-flighted, run)
    rig = _payload_rig()
    result = Runner(rig, store).run(protocol)
    assert (result.exit_status, result.samples) == ("completed", 8)
    assert [prompt.text for prompt in rig.operator.asked] == [MOUNT_25, REMOVE_25]
    home = tuple(robot_model("pkm5").home)
    assert rig.operator.at[-1] == home and rig.robot.log[-2][1] == home  # asked after the clean-up's move home
    # the loads the other way round: the plan itself takes the payload off (its last load is 0 kg), once
    rig = _payload_rig()
    reverse = _two_loads((2.5, 0))
    assert [text for text, _, _ in _payload_prompts(reverse)] == [MOUNT_25, REMOVE_25]
    assert Runner(rig, store).run(reverse).exit_status == "completed"
    assert [prompt.text for prompt in rig.operator.asked] == [MOUNT_25, REMOVE_25]
    rig = _payload_rig()
    assert Runner(rig, store).run(PoseAccuracy(cycles=2, velocities_pct=[100], settle_s=0)).samples == 10
    assert rig.operator.asked == []  # no load, nothing to ask


def test_a_stopped_run_takes_its_payload_off_and_its_resume_asks_for_it_again(store):
    protocol = _two_loads()
    rig = _payload_rig(stop_on=MOUNT_25)
    rig.operator.runner = Runner(rig, store)
    stopped = rig.operator.runner.run(protocol)  # stops at the checkpoint after the first 2.5 kg cycle
    assert (stopped.exit_status, stopped.samples) == ("aborted", 6)
    assert [prompt.text for prompt in rig.operator.asked] == [MOUNT_25, REMOVE_25]
    rig = _payload_rig()
    resumed = Runner(rig, store).resume_run(stopped.run_id)
    assert (resumed.exit_status, resumed.samples) == ("completed", 8)
    # before the first step it performs, not after: its samples are taken under the payload they are labelled with
    assert [prompt.text for prompt in rig.operator.asked] == [MOUNT_25, REMOVE_25]
    assert rig.operator.at[0] is None
    with Store(store.path, read_only=True) as reader:
        assert [s.values["load_kg"] for s in reader.samples(stopped.run_id)] == [0, 0, 0, 0, 2.5, 2.5, 2.5, 2.5]


class _StopAtCapture(BiasedInstrument):
    """Asks ``runner`` to stop (at its next checkpoint) during capture number ``at``."""

    def __init__(self, at: int):
        self.at, self.count, self.runner = at, 0, None

    def measure(self, capture):
        self.count += 1
        if self.count == self.at:
            self.runner.stop()
        return super().measure(capture)


def test_a_resume_between_two_loads_asks_for_the_next_load_only(store):
    # stopped at the checkpoint that closes the 2.5 kg block: the resume's first step is the 5 kg confirmation
    protocol = _two_loads((2.5, 5))
    rig = _payload_rig()
    rig.instrument = _StopAtCapture(at=4)
    rig.instrument.runner = Runner(rig, store)
    stopped = rig.instrument.runner.run(protocol)
    assert (stopped.exit_status, stopped.samples) == ("aborted", 4)
    assert [prompt.text for prompt in rig.operator.asked] == [MOUNT_25, REMOVE_25]
    rig = _payload_rig()
    assert Runner(rig, store).resume_run(stopped.run_id).exit_status == "completed"
    assert [prompt.text for prompt in rig.operator.asked] == [
        MOUNT_25.replace("2.5", "5"),
        REMOVE_25.replace("2.5", "5"),
    ]


def test_a_resume_with_only_the_clean_up_left_asks_for_the_removal_only(store):
    # every sample stored, the move home failed: the payload is still on, and only its removal is asked
    protocol = _two_loads()
    rig = _payload_rig()
    rig.robot.fail_after = 8  # the ninth move is the clean-up's move home
    failed = Runner(rig, store).run(protocol)
    assert (failed.exit_status, failed.samples) == ("failed", 8)
    assert [prompt.text for prompt in rig.operator.asked] == [MOUNT_25]
    rig = _payload_rig()
    assert Runner(rig, store).resume_run(failed.run_id).exit_status == "completed"
    assert [prompt.text for prompt in rig.operator.asked] == [REMOVE_25]


class _StopDuringRemoval(_PayloadOperator):
    def ask(self, prompt):
        if prompt.text.startswith("Remove"):
            self.runner.stop()
            self.runner.emergency_stop()
        return super().ask(prompt)


def test_a_stop_during_the_removal_leaves_a_completed_run_completed(store):
    rig = _rig()
    rig.operator = _StopDuringRemoval(rig.robot)
    rig.operator.runner = Runner(rig, store)
    result = rig.operator.runner.run(_two_loads())
    assert (result.exit_status, result.samples, result.reason) == ("completed", 8, None)


def test_a_withdrawn_removal_leaves_a_completed_run_completed(store, caplog):
    protocol = _two_loads()
    rig = _payload_rig(withdraw="Remove")
    with caplog.at_level(logging.WARNING, logger="bench.protocols.runner"):
        result = Runner(rig, store).run(protocol)
    assert (result.exit_status, result.samples, result.reason) == ("completed", 8, None)
    assert "the 2.5 kg payload may still be on the end effector" in caplog.text


@pytest.mark.parametrize("protocol_class, clause", [(MultiDirectional, "7.2.3"), (Drift, "7.6")])
def test_one_load_protocols_mount_their_load_and_refuse_several(protocol_class, clause):
    assert [load for _, load, _ in _payload_prompts(protocol_class(cycles=2, loads_kg=[3.0], settle_s=0))] == [3.0]
    with pytest.raises(ConfigError) as refused:
        protocol_class(cycles=2, loads_kg=[3.0, 0.3], source="p.toml")
    assert str(refused.value) == (
        f"p.toml: loads_kg = [3.0, 0.3]: {protocol_class.name} runs at one load "
        f"(ISO 9283 {clause}: rated), expected one value"
    )


def test_resume_sends_stored_prompt_readings_back(store):
    from bench.protocols.base import Protocol

    class Readings(Protocol):
        name = "test_readings"
        version = "1"

        def steps(self):
            total = 0.0
            for cycle in (1, 2, 3):
                total += yield Prompt("reading", field="depth_mm", unit="mm", pose="A", cycle=cycle, kind="depth")
                yield Move((110.0, 0.0, 320.0 + total / 100), 100.0, "A")
                yield Checkpoint(f"cycle {cycle}")

    failed = Runner(_rig(RecordingRobot(fail_after=1)), store).run(Readings())
    assert failed.exit_status == "failed" and failed.samples == 2  # the first two readings, then a move failed
    from bench.protocols import base

    base.PROTOCOLS["test_readings"] = Readings
    try:
        robot = RecordingRobot()
        rig = _rig(robot)
        resumed = Runner(rig, store).resume_run(failed.run_id)
    finally:
        del base.PROTOCOLS["test_readings"]
    assert resumed.exit_status == "completed" and resumed.samples == 3
    # readings 1 and 2 are stored, so the run restarts at the last checkpoint before reading 3; the stored
    # readings are sent back (running total 1.25 + 1.25 + 1.25) and only the third is asked
    assert len(rig.operator.asked) == 1
    assert [e[1][2] for e in robot.log if e[0] == "move"] == [pytest.approx(320.0375)]


# ---- emergency stop, withdrawn prompts, time base, hooks ---------------------------------------------------------


def _live_rig(robot):
    """A rig whose settles are real waits (rig.sleep None), 600 s at speed factor 1."""
    rig = _rig(robot)
    rig.sleep, rig.speed_factor = None, 1.0
    return rig


def test_emergency_stop_from_another_thread_cuts_a_settle_short_and_runs_no_clean_up(tmp_path, store):
    robot = RecordingRobot()
    run = RunInThread(tmp_path / "bench.db", _live_rig(robot), _small(settle_s=600))
    wait_until(lambda: isinstance(run.runner.current_step, Settle), "the first settle")
    run.runner.emergency_stop()
    result = run.finished()
    assert (result.exit_status, result.reason, result.samples, result.exception) == (
        "aborted",
        "emergency stop",
        0,
        None,
    )
    # the stop went out from the calling thread at once, again from the runner's, and no clean-up move (home)
    assert [entry[0] for entry in robot.log] == ["move", "stop", "stop", "shutdown"]
    assert robot.stopped_from == [threading.current_thread().name, "runner-thread"]
    assert (store.run(result.run_id).status, store.run(result.run_id).reason) == ("aborted", "emergency stop")


class _MoveUntilStopped(RecordingRobot):
    """Its second move lasts until stop() is called, then raises as the pkm5 driver does (ERR 8 STOPPED)."""

    def __init__(self):
        super().__init__()
        self.moving = threading.Event()
        self._stopped = threading.Event()

    def move_to(self, target, *, velocity_pct):
        super().move_to(target, velocity_pct=velocity_pct)
        if sum(entry[0] == "move" for entry in self.log) == 2:
            self.moving.set()
            assert self._stopped.wait(30)
            raise OSError("controller refused 'MOVE' with error 8 STOPPED")

    def stop(self):
        super().stop()
        self._stopped.set()


def test_emergency_stop_ends_a_move_in_flight_and_its_error_is_not_a_failure(tmp_path):
    robot = _MoveUntilStopped()
    run = RunInThread(tmp_path / "bench.db", _rig(robot), _small())
    assert robot.moving.wait(10)
    run.runner.emergency_stop()
    result = run.finished()
    assert (result.exit_status, result.reason, result.samples, result.exception) == (
        "aborted",
        "emergency stop",
        1,
        None,
    )
    assert [entry[0] for entry in robot.log] == ["move", "move", "stop", "stop", "shutdown"]  # nothing after it


def test_emergency_stop_before_the_run_ends_it_before_its_first_step(store):
    robot = RecordingRobot()
    runner = Runner(_rig(robot), store)
    runner.emergency_stop()
    result = runner.run(_small())
    assert (result.exit_status, result.reason, result.samples) == ("aborted", "emergency stop", 0)
    assert robot.log == [("stop",), ("stop",), ("shutdown",)]
    runner.emergency_stop()  # after the run: nothing is sent to the shut-down robot
    assert robot.log[-1] == ("shutdown",)


def test_emergency_stop_reason_survives_later_requests(tmp_path):
    robot = _MoveUntilStopped()
    run = RunInThread(tmp_path / "bench.db", _rig(robot), _small())
    assert robot.moving.wait(10)
    run.runner.emergency_stop()
    for refused in (run.runner.stop, run.runner.abort):  # e.g. the window closing after the e-stop
        with pytest.raises(TransitionError, match="cannot go from halting"):
            refused("stopped: window closed")
    assert run.finished().reason == "emergency stop"


def test_abort_cuts_a_settle_short_and_still_runs_the_clean_up(tmp_path):
    robot = RecordingRobot()
    run = RunInThread(tmp_path / "bench.db", _live_rig(robot), _small(settle_s=600))
    wait_until(lambda: isinstance(run.runner.current_step, Settle), "the first settle")
    run.runner.abort()
    result = run.finished()
    assert (result.exit_status, result.reason, result.samples) == ("aborted", "aborted by the operator", 0)
    assert [entry[0] for entry in robot.log] == ["move", "stop", "move", "shutdown"]
    assert robot.log[2][1] == pytest.approx((88.649, 0.0, 300.937, 0.0, 0.0))  # clean-up: home


class _Withdrawing(Answers):
    """Withdraws the first instruction prompt (e.g. Cancel in the window's dialog)."""

    def ask(self, prompt):
        self.asked.append(prompt)
        if prompt.field is None:
            raise PromptWithdrawn("cancelled in the calliper dialog")
        return 1.25


def test_withdrawn_prompt_aborts_without_clean_up_and_the_run_resumes(store):
    protocol = _two_loads()
    robot = RecordingRobot()
    rig = _rig(robot)
    rig.operator = _Withdrawing()
    result = Runner(rig, store).run(protocol)
    text = rig.operator.asked[0].text
    assert (result.exit_status, result.samples, result.exception) == ("aborted", 4, None)  # the 0 kg cycles
    assert result.reason == f"prompt withdrawn by the operator: {text} (cancelled in the calliper dialog)"
    assert robot.log[-2:] == [("stop",), ("shutdown",)]  # no clean-up move: the operator may be at the robot
    resumed = Runner(_rig(), store).resume_run(result.run_id)
    assert (resumed.exit_status, resumed.samples) == ("completed", 8)


def test_no_value_for_a_reading_is_a_failure_not_a_withdrawal(store):
    from bench.protocols.base import Protocol

    class OneReading(Protocol):
        name, version = "test_one_reading", "1"

        def steps(self):
            yield Prompt("depth", field="depth_mm", unit="mm", kind="depth")

    rig = _rig()
    rig.operator.ask = lambda prompt: None
    result = Runner(rig, store).run(OneReading())
    assert result.exit_status == "failed" and isinstance(result.exception, ConfigError)
    assert result.reason == (
        "ConfigError: prompt 'depth': no value given for depth_mm; an operator who will not "
        "answer raises PromptWithdrawn"
    )


class _SteppingClock:
    """A monotonic clock that advances ``tick_s`` at every reading, from ``start_s``."""

    def __init__(self, start_s, tick_s=0.25):
        self.now_s, self.tick_s = start_s, tick_s

    def __call__(self):
        self.now_s += self.tick_s
        return self.now_s


def test_sample_times_are_in_the_rig_time_base_and_stay_monotonic_across_a_resume(store):
    rig = _rig(RecordingRobot(fail_after=8))
    rig.speed_factor, rig.clock = 1000.0, _SteppingClock(5000.0)
    started, seen = [], []
    runner = Runner(
        rig,
        store,
        on_start=lambda r: started.append((r.run_id, r.samples_total, r.samples_stored)),
        on_sample=lambda r, sample: seen.append(sample),
    )
    failed = runner.run(_small())
    # one clock reading at the start and one per sample, 0.25 s apart: 250 simulated s per sample
    assert [s.t_s for s in store.samples(failed.run_id)] == [250.0 * k for k in range(1, 9)]
    assert store.run(failed.run_id).settings["time_base"] == "simulated s (wall x speed factor 1000)"
    rig = _rig()
    rig.speed_factor, rig.clock = 1000.0, _SteppingClock(0.0)  # a new process: its clock reads less than before
    Runner(
        rig,
        store,
        on_start=lambda r: started.append((r.run_id, r.samples_total, r.samples_stored)),
        on_sample=lambda r, sample: seen.append(sample),
    ).resume_run(failed.run_id)
    samples = sorted(store.samples(failed.run_id), key=lambda s: s.step_index)
    assert [s.t_s for s in samples] == [250.0 * k for k in range(1, 9)] + [2000 + 250.0 * k for k in range(1, 23)]
    assert started == [(failed.run_id, 30, 0), (failed.run_id, 30, 8)]
    assert [(s["step_index"], s["t_s"], s["values"], s["pose"], s["cycle"]) for s in seen] == [
        (s.step_index, s.t_s, s.values, s.pose, s.cycle) for s in samples
    ]


def test_hardware_time_base_is_wall_seconds_and_a_failing_hook_never_fails_the_run(store, caplog):
    rig = _rig()
    rig.speed_factor = 1.0

    def broken(runner, sample):
        raise RuntimeError("window gone")

    with caplog.at_level(logging.ERROR, logger="bench.protocols.runner"):
        result = Runner(rig, store, on_sample=broken).run(_small())
    assert (result.exit_status, result.samples) == ("completed", 30)
    assert store.run(result.run_id).settings["time_base"] == "wall s"
    assert sum("window gone" in record.exc_text for record in caplog.records if record.exc_text) == 30


def test_console_operator_reasks_until_valid_and_ctrl_d_withdraws_the_prompt(capsys):
    from bench.errors import PromptWithdrawn
    from bench.rigs.operators import ConsoleOperator
    from bench.steps import Prompt

    answers = iter(["abc", "300", "nan", "1" * 400, "12,5"])
    prompt = Prompt("Leg 1 length", field="length_mm", unit="mm", minimum=0.0, maximum=100.0)
    entry = ConsoleOperator(lambda _: next(answers)).ask(prompt)
    assert (entry, entry.typed) == (12.5, "12,5")  # the text as typed is kept beside the value
    err = capsys.readouterr().err
    assert "Leg 1 length: reading 'abc' is not a length; expected e.g. '12.34'" in err
    assert "Leg 1 length: 300 mm, expected 0 to 100 mm; try again" in err
    assert "reading 'nan' is not a length" in err and "has 400 digits, expected at most 15" in err
    # far from the commanded length: kept only when confirmed
    far = Prompt(
        "Leg 1 length", field="length_mm", unit="mm", minimum=0.0, maximum=100.0, commanded={"cmd_length_mm": 50.0}
    )
    answers = iter(["60", "n", "60", "y"])
    assert ConsoleOperator(lambda _: next(answers)).ask(far) == 60.0
    assert capsys.readouterr().err.count("from the expected 50 mm; keep it? [y/N]") == 2

    def end_of_input(_):
        raise EOFError

    with pytest.raises(PromptWithdrawn, match="Ctrl-D"):
        ConsoleOperator(end_of_input).ask(prompt)


class _LatchingRobot(RecordingRobot):
    """Records an emergency stop apart from a plain stop."""

    def emergency_stop(self):
        self.log.append(("emergency_stop",))


def test_the_runners_emergency_stop_latches_where_the_robot_can_and_abort_does_not(store):
    robot = _LatchingRobot()
    runner = Runner(_rig(robot), store)
    runner.emergency_stop()
    runner.run(_small())
    assert robot.log[0] == ("emergency_stop",)  # from the calling thread: the latching stop


def test_pkm5_emergency_stop_refuses_every_later_move_until_released():
    from bench.errors import LinkError
    from bench.simulators.rig import simulated_rig

    rig = simulated_rig("pkm5", seed=1, speed_factor=20000)
    controller = rig.robot.controller
    try:
        rig.robot.move_to((110.0, 0.0, 320.0), velocity_pct=100)
        rig.robot.emergency_stop()
        reached = controller.position().steps
        with pytest.raises(LinkError, match="refused: an emergency stop is latched"):
            rig.robot.move_to((100.0, 0.0, 310.0), velocity_pct=100)
        assert controller.position().steps == reached  # nothing was sent
        rig.robot.stop()  # a plain stop (abort) does not latch a second time, and release_stop() releases the latch
        rig.robot.release_stop()
        rig.robot.move_to((100.0, 0.0, 310.0), velocity_pct=100)
        assert controller.position().steps != reached
    finally:
        rig.close()


def test_delta_rig_refuses_moves_once_emergency_stopped():
    from bench.errors import LinkError
    from bench.rigs.movers import DeltaMover

    class Controller:
        def __init__(self):
            self.log = []

        def move_to(self, point, **kwargs):
            self.log.append(("move", point))

        def stop(self):
            self.log.append(("stop",))

    controller = Controller()
    mover = DeltaMover(controller)
    mover.move_to((0.0, 0.0, -200.0), velocity_pct=100)
    mover.emergency_stop()
    with pytest.raises(LinkError, match="refused: an emergency stop is latched"):
        mover.move_to((0.0, 0.0, -190.0), velocity_pct=100)
    assert controller.log == [("move", (0.0, 0.0, -200.0)), ("stop",)]


@given(st.text(max_size=40))
@settings(max_examples=500, deadline=None)
def test_typed_entries_are_a_finite_reading_within_bounds_or_one_line(text):
    from bench.errors import ConfigError
    from bench.rigs.operators import parse_entry
    from bench.steps import Prompt

    prompt = Prompt("Tilt alpha", field="a_deg", unit="deg", minimum=-45.0, maximum=45.0)
    try:
        value, _ = parse_entry(prompt, text)
    except ConfigError as exc:
        assert "\n" not in str(exc) and str(exc).startswith("Tilt alpha")
    else:
        assert math.isfinite(value) and -45.0 <= value <= 45.0
