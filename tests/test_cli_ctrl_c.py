"""Ctrl-C at a terminal during ``bench run`` on the simulator (issue 31, items 13 and 14).

A terminal sends SIGINT to its whole foreground process group: each test starts ``bench run`` as the leader of its own
process group (as a shell starts a job) and signals that group with ``os.killpg``, so the simulator child gets the
signal too unless it runs in a session of its own. No test waits on a clock: each next signal goes once the
previous one's message is on stderr."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path

import pytest
from cli_runs import BENCH, wait_for_samples

from bench.store import Store

ROOT = Path(__file__).resolve().parents[1]
QUICK = ROOT / "examples" / "iso9283_pose_quick.toml"
PAUSE_MENU = "paused: [r]esume"
PAUSING = "pausing at the next checkpoint"
#: Longest wait for a message; a run that never says it fails the test instead of hanging it.
TIMEOUT_S = 90.0


class TerminalJob:
    """``bench run`` as a terminal's foreground job: its own process group, stdin a pipe typed into."""

    def __init__(self, tmp_path: Path) -> None:
        self.store = tmp_path / "b.db"
        self.err_path = tmp_path / "stderr.txt"
        self._err = open(self.err_path, "w")
        self.process = subprocess.Popen(
            [BENCH, "run", str(QUICK), "--sim", "--store", str(self.store), "--no-progress", "--speed-factor", "40"],
            stdin=subprocess.PIPE,
            stdout=subprocess.DEVNULL,
            stderr=self._err,
            text=True,
            process_group=0,
        )

    def stderr(self) -> str:
        return self.err_path.read_text()

    def ctrl_c(self) -> None:
        os.killpg(self.process.pid, signal.SIGINT)  # what the terminal does: the whole foreground group

    def wait_for_text(self, text: str, count: int = 1) -> None:
        deadline = time.monotonic() + TIMEOUT_S
        while self.stderr().count(text) < count:
            assert self.process.poll() is None, f"bench ended before saying {text!r}:\n{self.stderr()}"
            assert time.monotonic() < deadline, f"no {text!r} x{count} within {TIMEOUT_S:g} s:\n{self.stderr()}"
            time.sleep(0.02)

    def type(self, line: str) -> None:
        self.process.stdin.write(line + "\n")
        self.process.stdin.flush()

    def resume(self) -> None:
        """Type ``r`` at the menu and wait until the run has stored a sample after it (it runs again)."""
        with Store(self.store) as opened:
            (run,) = opened.runs()
        self.type("r")
        wait_for_samples(self.store, self.process, run.n_samples + 1)

    def finish(self):
        self.process.stdin.close()
        self.process.wait(TIMEOUT_S)
        self._err.close()
        with Store(self.store) as opened:
            (run,) = opened.runs()
        return self.process.returncode, run


def test_ctrl_c_pauses_and_the_simulator_survives_it(tmp_path):
    job = TerminalJob(tmp_path)
    wait_for_samples(job.store, job.process, 1)
    job.ctrl_c()
    job.wait_for_text(PAUSE_MENU)
    job.type("s")  # stop: the run ends at this checkpoint, its clean-up moves run on the living simulator
    code, run = job.finish()
    assert (code, run.status) == (1, "aborted"), job.stderr()
    assert run.reason.startswith("stopped by the operator at checkpoint"), run.reason
    assert "LinkError" not in job.stderr()


@pytest.mark.parametrize("second_ctrl_c_after", [PAUSING, PAUSE_MENU])
def test_after_a_resume_ctrl_c_pauses_again_and_the_next_ctrl_c_aborts(tmp_path, second_ctrl_c_after):
    """The next Ctrl-C after a resume pauses; the one after it aborts, whether the pause is still pending
    (PAUSING said) or the menu is shown (it said "cannot pause while paused" and failed the run)."""
    job = TerminalJob(tmp_path)
    wait_for_samples(job.store, job.process, 1)
    job.ctrl_c()
    job.wait_for_text(PAUSE_MENU)
    job.resume()
    job.ctrl_c()  # running again: pause
    job.wait_for_text(second_ctrl_c_after, count=2)
    job.ctrl_c()  # abort now, as the message says
    code, run = job.finish()
    assert (code, run.status, run.reason) == (1, "aborted", "interrupted (Ctrl-C)"), job.stderr()
    assert "Traceback" not in job.stderr() and "cannot pause while paused" not in job.stderr()
