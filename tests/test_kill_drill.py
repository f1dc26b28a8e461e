"""The kill -9 drill on a hardware-shaped rig: the pkm5 simulator on a pty driven through ``--port`` (it outlives
the host, as a controller does), the mice fed from its truth through FIFOs. ``bench run`` is killed with SIGKILL
at 10 seeded random moments (a sample count, then a random delay into the next move or settle), each time followed
by ``bench resume``. In the end: every sample once (15/15), the rows stored before each kill byte-identical, and
every row agrees with the simulator's truth log as well as an uninterrupted run does: measured minus true is one
offset (the registration at home) for every row, within 0.05 mm (a resume registered away from home is off by
tens of mm).

Found by this drill (strict xfail below): the rows of each segment agree with each other within 0.05 mm, but each
resume re-registers the mice at home after homing from wherever the kill left the robot, and the true home pose
depends on the approach direction (the joints' backlash), so segments differ by up to about 2 mm. Closing it needs
the check pose of issue 15 ("measure a check pose and refuse to continue") or homing from one side."""

from __future__ import annotations

import json
import os
import random
import select
import signal
import subprocess
import time
from dataclasses import dataclass
from datetime import datetime

import numpy as np
import pytest

from cli_runs import BENCH

from bench.store import Store

TRUTH_TOLERANCE_MM = 0.05
KILLS = 10
SAMPLES = 15


def _stored(store) -> tuple[int | None, int, str | None]:
    """(run id, samples stored, status) of the store's only run, or (None, 0, None) before it exists."""
    if not store.exists():
        return None, 0, None
    with Store(store, read_only=True) as opened:
        runs = opened.runs()
        return (runs[0].id, runs[0].n_samples, runs[0].status) if runs else (None, 0, None)


def _rows(store, run_id) -> dict[int, tuple]:
    with Store(store, read_only=True) as opened:
        return {row[0]: tuple(row) for row in opened.stored_rows(run_id)}


def _true_xyz(truth: list[dict], wall_s: float) -> np.ndarray:
    entry = [e for e in truth if e["t_wall_s"] <= wall_s][-1]
    fields = entry["pose_fields"]
    return np.array([entry["pose"][fields.index(axis)] for axis in ("x_mm", "y_mm", "z_mm")])


@dataclass
class Drill:
    samples: list            # the final samples of the run
    final: dict[int, tuple]  # its rows as stored
    snapshots: list[dict[int, tuple]]  # the rows stored when each kill landed
    kills_at: list[int]      # samples stored at each kill
    status: str | None
    truth: list[dict]

    def offsets_mm(self, samples=None) -> np.ndarray:
        """Measured minus true (x, y, z) of each sample, mm."""
        return np.array([[s.values[a] for a in ("x_mm", "y_mm", "z_mm")]
                         - _true_xyz(self.truth, datetime.fromisoformat(s.wall_utc).timestamp())
                         for s in (self.samples if samples is None else samples)])

    def segments(self) -> list[list]:
        """The samples grouped by the segment (one registration of the mice) that stored them."""
        bounds = [set(snapshot) for snapshot in self.snapshots] + [set(self.final)]
        groups, seen = [], set()
        for steps in bounds:
            group = [s for s in self.samples if s.step_index in steps - seen]
            seen |= steps
            if group:
                groups.append(group)
        return groups


def _spread_mm(offsets: np.ndarray) -> float:
    return float(np.abs(offsets - np.median(offsets, axis=0)).max())


@pytest.fixture(scope="module")
def drill(tmp_path_factory) -> Drill:
    tmp_path = tmp_path_factory.mktemp("drill")
    protocol = tmp_path / "pose.toml"
    protocol.write_text('protocol = "iso9283_pose"\nrobot = "pkm5"\ncycles = 3\nvelocities_pct = [100]\n'
                        'settle_s = 0.1\n')
    mice, truth_log, store = tmp_path / "mice", tmp_path / "truth.jsonl", tmp_path / "b.db"
    mice.mkdir()
    simulator = subprocess.Popen([BENCH, "sim", "pkm5", "--mice", str(mice), "--speed-factor", "50", "--seed", "5",
                                  "--truth", str(truth_log)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                 text=True)
    rng = random.Random(15)
    snapshots: list[dict[int, tuple]] = []
    kills_at: list[int] = []
    try:
        ready, _, _ = select.select([simulator.stdout], [], [], 60)
        assert ready, "the simulator printed no device path within 60 s"
        rig = ["--port", simulator.stdout.readline().strip(), "--mouse-xy", str(mice / "mouse_xy.fifo"),
               "--mouse-xz", str(mice / "mouse_xz.fifo"), "--store", str(store), "--no-progress"]
        for kill in range(KILLS + 1):
            run_id, stored, _ = _stored(store)
            command = ["run", str(protocol)] if run_id is None else ["resume", str(run_id)]
            process = subprocess.Popen([BENCH, *command, *rig], stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                       stderr=subprocess.PIPE, text=True)
            if kill == KILLS:  # the last segment runs to the end
                out, err = process.communicate(timeout=300)
                assert process.returncode == 0, err
                break
            target = min(SAMPLES - 1, stored + rng.randint(0, 2))
            deadline = time.monotonic() + 120
            while _stored(store)[1] < target and process.poll() is None:
                assert time.monotonic() < deadline, f"no {target} samples within 120 s"
                time.sleep(0.02)
            time.sleep(rng.uniform(0.0, 0.4))  # into the next move, settle or capture
            assert process.poll() is None, process.communicate()
            os.kill(process.pid, signal.SIGKILL)
            process.communicate(timeout=30)
            run_id, stored, status = _stored(store)
            kills_at.append(stored)
            if run_id is not None:
                assert status == "interrupted"
                snapshots.append(_rows(store, run_id))
    finally:
        simulator.send_signal(signal.SIGTERM)
        simulator.communicate(timeout=30)
    run_id, stored, status = _stored(store)
    truth = [json.loads(line) for line in truth_log.read_text().splitlines()]
    with Store(store, read_only=True) as opened:
        samples = opened.samples(run_id)
    return Drill(samples, _rows(store, run_id), snapshots, kills_at, status, truth)


@pytest.mark.slow
def test_kill_9_at_ten_random_moments_loses_duplicates_and_changes_no_sample(drill):
    assert (drill.status, len(drill.samples)) == ("completed", SAMPLES)
    assert len({s.step_index for s in drill.samples}) == SAMPLES
    assert len(drill.kills_at) == KILLS and len(set(drill.kills_at)) >= 5, drill.kills_at  # spread over the run
    for snapshot in drill.snapshots:  # nothing stored before a kill changed, byte for byte
        assert {step: drill.final[step] for step in snapshot} == snapshot
    for segment in drill.segments():  # one registration: the rows agree with the truth up to one offset
        assert _spread_mm(drill.offsets_mm(segment)) < TRUTH_TOLERANCE_MM, drill.offsets_mm(segment)


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="each resume re-registers the mice at a home whose true pose depends on the "
                                       "approach (backlash): segments differ by up to ~2 mm; needs a check pose")
def test_kill_9_at_ten_random_moments_every_row_within_0_05_mm_of_the_truth(drill):
    assert _spread_mm(drill.offsets_mm()) < TRUTH_TOLERANCE_MM, drill.offsets_mm()
