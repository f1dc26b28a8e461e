"""The runner's sample commits on the store's writer thread (bench.store.sample_writer): each commit overlaps the
next move, a sample is reported only once durable, and a failed commit fails the run before anything else is
measured. Deterministic: a commit is held until the runner either starts the next move or waits for the commit, and
the order of what happened is read from one log."""

from __future__ import annotations

import threading

import pytest
from runner_support import StandInMover

from bench.protocols import Measurement, Rig, Runner
from bench.protocols.iso9283 import PoseAccuracy
from bench.store import Store, sample_writer
from bench.store.connection import StoreError
from bench.store.sample_writer import SampleWriter

SAMPLES = 30  # 5 poses x 3 cycles x 2 velocities


class LoggingRobot(StandInMover):
    def __init__(self, log, moved):
        self.log, self.moved = log, moved

    def move_to(self, target, *, velocity_pct):
        self.log.append(("move", tuple(target)))
        self.moved.set()

    def stop(self):
        self.log.append(("stop",))

    def shutdown(self):
        self.log.append(("shutdown",))

    def settings(self):
        return {"driver": "logging"}


class LoggingInstrument:
    def __init__(self, log):
        self.log, self.count = log, 0

    def measure(self, capture):
        self.count += 1
        self.log.append(("measure", self.count))
        x, y, z = (capture.commanded[k] for k in ("cmd_x_mm", "cmd_y_mm", "cmd_z_mm"))
        return Measurement({"x_mm": x, "y_mm": y, "z_mm": z}, raw=None)

    def settings(self):
        return {"instrument": "logging"}


class NoOperator:
    def ask(self, prompt):
        return None


@pytest.fixture()
def held_commits(monkeypatch):
    """Every commit waits until the runner moves the robot or waits for it; the log records the order."""
    log, release = [], threading.Event()
    real_insert, real_add, real_wait = sample_writer.insert_sample_row, SampleWriter.add, SampleWriter.wait
    real_checkpoint = sample_writer.checkpoint_wal

    def add(self, *args, **kwargs):
        release.clear()
        real_add(self, *args, **kwargs)
        log.append(("taken", len([e for e in log if e[0] == "taken"]) + 1))

    def wait(self):
        if self._pending is not None:
            log.append(("runner waits",))
        release.set()
        return real_wait(self)

    def insert(db, row):
        release.wait()
        real_insert(db, row)
        log.append(("durable", len([e for e in log if e[0] == "durable"]) + 1))

    monkeypatch.setattr(SampleWriter, "add", add)
    monkeypatch.setattr(SampleWriter, "wait", wait)

    def checkpoint(db):
        real_checkpoint(db)
        log.append(("checkpoint", len([e for e in log if e[0] == "durable"])))

    monkeypatch.setattr(sample_writer, "insert_sample_row", insert)
    monkeypatch.setattr(sample_writer, "checkpoint_wal", checkpoint)
    return log, release


def _rig(log, moved):
    return Rig(LoggingRobot(log, moved), LoggingInstrument(log), NoOperator(), speed_factor=1e6, sleep=lambda s: None)


def _protocol():
    return PoseAccuracy(cycles=3, velocities_pct=[100, 10], settle_s=0.5)


def test_each_commit_overlaps_the_next_move_and_a_sample_is_reported_only_once_durable(tmp_path, held_commits):
    log, release = held_commits
    with Store(tmp_path / "bench.db") as store:
        runner = Runner(_rig(log, release), store, on_sample=lambda r, s: log.append(("reported", r.samples_stored)))
        result = runner.run(_protocol())
        assert (result.exit_status, result.samples, runner.samples_stored) == ("completed", SAMPLES, SAMPLES)
    where = {entry: i for i, entry in enumerate(log)}
    overlapped = 0
    for k in range(1, SAMPLES + 1):
        taken, durable, reported = where[("taken", k)], where[("durable", k)], where[("reported", k)]
        assert taken < durable < reported  # told only once on disk
        if ("measure", k + 1) in where:
            assert durable < where[("measure", k + 1)]  # the next sample is taken only after this one is durable
        between = [entry[0] for entry in log[taken + 1 : durable]]
        assert between[:1] in (["move"], ["runner waits"])  # what released the commit
        overlapped += between[:1] == ["move"]
    # every commit overlaps the next move (the last one: the clean-up move): a cycle's checkpoint step queues the
    # store's checkpoint behind its 5th commit, and the next cycle's first sample is taken after both
    assert overlapped == SAMPLES
    checkpoints = [i for i, entry in enumerate(log) if entry[0] == "checkpoint"]
    assert [log[i] for i in checkpoints] == [("checkpoint", k) for k in range(5, SAMPLES + 1, 5)]
    for i, k in zip(checkpoints, range(5, SAMPLES, 5)):
        assert where[("durable", k)] < i < where[("measure", k + 1)]  # in order; done before the next sample


def test_a_failed_commit_fails_the_run_before_anything_else_is_measured(tmp_path, monkeypatch):
    log, moved = [], threading.Event()
    real_insert, commits = sample_writer.insert_sample_row, []

    def insert(db, row):
        commits.append(row[1])
        if len(commits) == 4:
            raise StoreError(f"store {tmp_path / 'bench.db'}: disk I/O error; the file is damaged")
        real_insert(db, row)

    monkeypatch.setattr(sample_writer, "insert_sample_row", insert)
    reported = []
    with Store(tmp_path / "bench.db") as store:
        rig = _rig(log, moved)
        result = Runner(rig, store, on_sample=lambda r, s: reported.append(s["step_index"])).run(_protocol())
        stored = sorted(store.stored_steps(result.run_id))
        assert store.run(result.run_id).status == "failed"
    assert result.exit_status == "failed" and result.reason.startswith("StoreError: store ")
    assert "disk I/O error" in result.reason
    assert stored == commits[:3] and reported == commits[:3] and result.samples == 3
    # the 5th move ran during the 4th commit; the 5th capture was never measured: the commit's failure came first
    assert (len([e for e in log if e[0] == "move"]), rig.instrument.count) == (5, 4)
    assert log[-2:] == [("stop",), ("shutdown",)]


def test_a_store_in_memory_commits_at_once_and_one_commit_is_in_flight_at_a_time(tmp_path):
    with Store(":memory:") as store:
        run_id = store.start_run(protocol_name="p", protocol_version="1", robot="pkm5", config={})
        writer = SampleWriter(store)
        writer.add(run_id, 0, values={"x_mm": 1.0}, kind="pose", pose="P1", cycle=1, t_s=0.0, raw=None, report="0")
        assert store.stored_steps(run_id) == {0}  # at once, on this thread
        with pytest.raises(RuntimeError, match="expected wait\\(\\) first"):
            writer.add(run_id, 1, values={"x_mm": 1.0}, kind="pose", pose="P1", cycle=1, t_s=0.0, raw=None)
        assert writer.wait() == "0" and writer.wait() is None
        writer.close()
    with Store(tmp_path / "bench.db") as store:
        run_id = store.start_run(protocol_name="p", protocol_version="1", robot="pkm5", config={})
        writer = SampleWriter(store)
        writer.add(run_id, 0, values={"x_mm": 1.0}, kind="pose", pose="P1", cycle=1, t_s=0.0, raw=None, report="0")
        assert writer.wait() == "0" and store.stored_steps(run_id) == {0}
        writer.add(run_id, 0, values={"x_mm": 2.0}, kind="pose", pose="P1", cycle=1, t_s=0.0, raw=None)
        with pytest.raises(Exception, match="step 0 already has a stored sample"):
            writer.wait()
        writer.close()
        assert [s.values for s in store.samples(run_id)] == [{"x_mm": 1.0}]


def test_a_pause_requested_as_the_checkpoint_is_reached_waits_for_the_cycles_commits_first(
    tmp_path, held_commits, monkeypatch
):
    # the request comes from another thread (a window's Pause button) between the runner's look at the requests
    # and its pause: the operator must still see every sample of the cycle durable and the .db file complete
    log, release = held_commits
    real_at_checkpoint, asked = Runner._at_checkpoint, []

    def request_arrives_now(self, step):
        if not asked:
            asked.append(True)
            self.request_pause()
        return real_at_checkpoint(self, step)

    monkeypatch.setattr(Runner, "_at_checkpoint", request_arrives_now)

    def on_pause(runner):
        log.append(("paused", runner.samples_stored))
        runner.resume()

    with Store(tmp_path / "bench.db") as store:
        runner = Runner(_rig(log, release), store, on_pause=on_pause)
        result = runner.run(_protocol())
        assert (result.exit_status, result.samples) == ("completed", SAMPLES)
    paused = log.index(("paused", 5))  # the first checkpoint comes after the cycle's 5 samples, all reported
    assert log.index(("durable", 5)) < log.index(("checkpoint", 5)) < paused
    assert [e for e in log[log.index(("taken", 5)) : paused] if e[0] == "move"] == []  # the robot waited too


def test_a_robot_failure_during_a_failed_commit_names_both(tmp_path, monkeypatch):
    """The 5th move fails while the 4th sample's commit fails: the run's stored reason names the robot's failure
    and the lost sample, not the first alone."""
    log, moved = [], threading.Event()
    real_insert, commits = sample_writer.insert_sample_row, []

    def insert(db, row):
        commits.append(row[1])
        if len(commits) == 4:
            raise StoreError("store: disk I/O error")
        real_insert(db, row)

    class FailingRobot(LoggingRobot):
        def move_to(self, target, *, velocity_pct):
            super().move_to(target, velocity_pct=velocity_pct)
            if len([e for e in self.log if e[0] == "move"]) == 5:
                raise RuntimeError("link lost")

    monkeypatch.setattr(sample_writer, "insert_sample_row", insert)
    with Store(tmp_path / "bench.db") as store:
        rig = Rig(
            FailingRobot(log, moved), LoggingInstrument(log), NoOperator(), speed_factor=1e6, sleep=lambda s: None
        )
        result = Runner(rig, store).run(_protocol())
        stored_reason = store.run(result.run_id).reason
    assert result.exit_status == "failed"
    assert stored_reason == (
        "RuntimeError: link lost; the last sample's commit failed: StoreError: store: disk I/O error"
    )
