"""The runner's emergency stop on the real pkm5 simulator over its pty, sent from another thread: a move in flight
is cut by the controller (ERR 8 STOPPED), a settle is cut short, and the run ends aborted without clean-up."""

from __future__ import annotations

import threading

import pytest
from runner_support import RunInThread, wait_until

from bench.protocols import Capture, Move, Settle
from bench.protocols.base import Protocol
from bench.simulators.rig import simulated_rig
from bench.steps import commanded_values
from bench.store import Store

TARGET = (110.0, 0.0, 320.0, 0.0, 0.0)


class _MoveSettleCapture(Protocol):
    """One move at ``velocity_pct``, a settle of ``settle_s``, a capture; the clean-up moves home."""

    name, version, robots = "test_estop", "1", ("pkm5",)

    def __init__(self, velocity_pct: float, settle_s: float) -> None:
        super().__init__()
        self.velocity_pct, self.settle_s = velocity_pct, settle_s

    def steps(self):
        yield Move(TARGET, self.velocity_pct, "A")
        yield Settle(self.settle_s)
        yield Capture("A", 1, commanded=commanded_values(TARGET))

    def final_steps(self):
        yield Move((88.649, 0.0, 300.937, 0.0, 0.0), 100.0, "home")


class _Watched:
    """The rig's real mover (driver on the pty), recording how each move ended and which thread sent each stop."""

    def __init__(self, mover) -> None:
        self.mover = mover
        self.moves: list[str] = []
        self.stops: list[str] = []

    def move_to(self, target, *, velocity_pct):
        try:
            self.mover.move_to(target, velocity_pct=velocity_pct)
        except Exception as exc:
            self.moves.append(f"{type(exc).__name__}: {exc}")
            raise
        self.moves.append("done")

    kind = "pkm5"

    @property
    def geometry(self):
        return self.mover.geometry

    def move_actuator(self, axis, stroke_mm, *, velocity_pct):
        self.mover.move_actuator(axis, stroke_mm, velocity_pct=velocity_pct)

    def stop(self):
        self.stops.append(threading.current_thread().name)
        self.mover.stop()

    def emergency_stop(self):
        self.stops.append(threading.current_thread().name)
        self.mover.emergency_stop()

    def shutdown(self):
        self.mover.shutdown()

    def settings(self):
        return self.mover.settings()


@pytest.fixture()
def rig_at():
    rigs = []

    def make(speed_factor):
        rig = simulated_rig("pkm5", seed=3, speed_factor=speed_factor)
        rig.robot = _Watched(rig.robot)
        rigs.append(rig)
        return rig

    yield make
    for rig in rigs:
        rig.close()


def test_emergency_stop_during_a_move_on_the_simulator(tmp_path, rig_at):
    rig = rig_at(1.0)  # real time, 1 % of 200 steps/s: the move would take hours
    link = rig.robot.mover.controller.link
    on_the_wire = threading.Event()
    write = link.write

    def watched_write(data, *, command):
        write(data, command=command)
        if command == "MOVE":
            on_the_wire.set()

    link.write = watched_write
    run = RunInThread(tmp_path / "bench.db", rig, _MoveSettleCapture(velocity_pct=1.0, settle_s=0.0))
    assert on_the_wire.wait(10)
    run.runner.emergency_stop()
    result = run.finished()
    assert (result.exit_status, result.reason, result.samples, result.exception) == (
        "aborted",
        "emergency stop",
        0,
        None,
    )
    (ended,) = rig.robot.moves  # the controller cut the move; no clean-up move followed
    assert "controller refused 'MOVE' with error 8 STOPPED" in ended
    assert rig.robot.stops == [threading.current_thread().name, "runner-thread"]
    with Store(tmp_path / "bench.db") as store:
        assert (store.run(result.run_id).status, store.run(result.run_id).reason) == ("aborted", "emergency stop")


def test_emergency_stop_cuts_a_settle_short_on_the_simulator(tmp_path, rig_at):
    rig = rig_at(1000.0)
    protocol = _MoveSettleCapture(velocity_pct=100.0, settle_s=600_000.0)  # 600 s of wall time at 1000x
    run = RunInThread(tmp_path / "bench.db", rig, protocol)
    wait_until(lambda: isinstance(run.runner.current_step, Settle), "the settle")
    run.runner.emergency_stop()
    result = run.finished()
    assert (result.exit_status, result.reason, result.samples) == ("aborted", "emergency stop", 0)
    assert rig.robot.moves == ["done"] and rig.robot.stops == [threading.current_thread().name, "runner-thread"]
