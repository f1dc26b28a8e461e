"""A campaign on a hardware-shaped rig survives line noise: the pkm5 simulator on a pty driven through ``--port``
with ``--garbage-every-s 0.008`` (8 random bytes every 8 ms, ~600 bytes piling up during each 0.6 s settle), the
mice fed from the simulator's truth through FIFOs. Every stored pose must agree with the truth log as well as a
noise-free run does: measured minus true is the same offset (the registration at home) for every row, within
0.05 mm."""

from __future__ import annotations

import json
import logging
import select
import subprocess
from datetime import datetime
from pathlib import Path

import numpy as np
import pytest
from cli_runs import BENCH

from bench.cli import main
from bench.store import Store

TRUTH_TOLERANCE_MM = 0.05


def _true_pose_at(truth: list[dict], wall_s: float) -> np.ndarray:
    """The true pose after the last move that ended before ``wall_s`` (the truth log's wall time, s)."""
    before = [entry for entry in truth if entry["t_wall_s"] <= wall_s]
    assert before, f"no move ended before {wall_s}"
    entry = before[-1]
    fields = entry["pose_fields"]
    return np.array([entry["pose"][fields.index(axis)] for axis in ("x_mm", "y_mm", "z_mm")])


@pytest.mark.slow
def test_a_campaign_under_line_noise_completes_with_the_true_numbers(tmp_path, capsys, caplog):
    protocol = tmp_path / "pose.toml"
    protocol.write_text(
        'protocol = "iso9283_pose"\nrobot = "pkm5"\ncycles = 2\nvelocities_pct = [100]\nsettle_s = 0.6\n'
    )
    mice, truth_log = tmp_path / "mice", tmp_path / "truth.jsonl"
    mice.mkdir()
    simulator = subprocess.Popen(
        [
            BENCH,
            "sim",
            "pkm5",
            "--mice",
            str(mice),
            "--garbage-every-s",
            "0.008",
            "--speed-factor",
            "500",
            "--seed",
            "3",
            "--truth",
            str(truth_log),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        ready, _, _ = select.select([simulator.stdout], [], [], 60)
        assert ready, "the simulator printed no device path within 60 s"
        port = simulator.stdout.readline().strip()
        store = tmp_path / "b.db"
        with caplog.at_level(logging.WARNING, logger="bench.robots.pkm5"):
            assert (
                main(
                    [
                        "run",
                        str(protocol),
                        "--port",
                        port,
                        "--mouse-xy",
                        str(mice / "mouse_xy.fifo"),
                        "--mouse-xz",
                        str(mice / "mouse_xz.fifo"),
                        "--store",
                        str(store),
                        "--no-progress",
                    ]
                )
                == 0
            )
    finally:
        simulator.terminate()
        simulator.communicate(timeout=30)
    noise = [r.getMessage() for r in caplog.records if "dropped line" in r.getMessage()]
    assert noise, "the noise never reached the driver"
    truth = [json.loads(line) for line in truth_log.read_text().splitlines()]
    with Store(store, read_only=True) as opened:
        (run,) = opened.runs()
        samples = opened.samples(run.id)
    assert (run.status, len(samples)) == ("completed", 10)
    offsets = np.array(
        [
            [s.values[a] for a in ("x_mm", "y_mm", "z_mm")]
            - _true_pose_at(truth, datetime.fromisoformat(s.wall_utc).timestamp())
            for s in samples
        ]
    )
    spread_mm = np.abs(offsets - np.median(offsets, axis=0)).max()
    assert spread_mm < TRUTH_TOLERANCE_MM, offsets
