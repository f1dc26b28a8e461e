"""An integrity check before appending to a store that was not closed cleanly (a run left ``running`` by a process
that is gone): a damaged store is refused in one line before anything is written; a healthy one is appended to."""

from __future__ import annotations

import logging
import signal
import sqlite3
import subprocess
from pathlib import Path

import pytest
from cli_lines import one_error_line as _one_error_line
from cli_runs import BENCH, wait_for_samples

from bench.cli import main
from bench.store import Store
from bench.store.recovery import StoreDamaged, interrupted_runs

ROOT = Path(__file__).resolve().parents[1]
QUICK = ROOT / "examples" / "iso9283_pose_quick.toml"
PAGE = 4096


def _interrupted_store(path: Path, samples: int = 300) -> Path:
    """A store whose run 1 was left ``running`` by its writer (closed without settling: the lock is released, as
    the kernel releases it when a writer is killed)."""
    with Store(path) as store:
        run_id = store.start_run(protocol_name="p", protocol_version="1", robot="pkm5", config={})
        for step in range(samples):
            store.add_sample(run_id, step, values={"x_mm": step * 0.5}, t_s=float(step))
    return path


def _damage_a_sample_page(path: Path) -> int:
    """Overwrite one leaf page of the samples table (not its root, not the runs table) with bytes 0x5a, as a bad
    disk block or a torn copy would; returns the page number."""
    with sqlite3.connect(path) as db:
        leaves = [
            row[0]
            for row in db.execute(
                "SELECT pageno FROM dbstat WHERE name = 'samples' AND pagetype = 'leaf' ORDER BY pageno"
            )
        ]
        (page_size,) = db.execute("PRAGMA page_size").fetchone()
    db.close()
    assert page_size == PAGE and len(leaves) > 3
    page = leaves[len(leaves) // 2]
    with open(path, "r+b") as file:
        file.seek((page - 1) * PAGE + 8)  # inside the page: its header's first bytes kept, its cells overwritten
        file.write(b"\x5a" * (PAGE - 8))
    return page


def test_a_damaged_store_left_by_an_interrupted_run_is_refused_before_anything_is_written(tmp_path, capsys):
    store = _interrupted_store(tmp_path / "bench.db")
    page = _damage_a_sample_page(store)
    before = store.read_bytes()
    for command in (["run", str(QUICK), "--sim", "--no-progress"], ["resume", "1", "--no-progress"]):
        assert main([*command, "--store", str(store)]) == 1
        line = _one_error_line(capsys)
        assert line.startswith(
            f"bench: error: store {store}: not closed cleanly (run 1 interrupted) and damaged: integrity: "
        ), line
        assert f"Page {page}" in line or f"page {page}" in line, line
        assert line.endswith(
            f"nothing was written: list the damage with `bench store check {store}`, keep a copy "
            f"with `bench backup COPY.db --store {store}`, and run into a new store (--store NEW.db)"
        )
    assert store.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bench.db"]  # no second run, no lock, no journal left
    with pytest.raises(StoreDamaged, match="not closed cleanly"):
        Store(store)
    with Store(store, read_only=True) as reader:  # readers are not refused: the runs can still be listed
        assert [(r.id, r.status) for r in reader.runs()] == [(1, "interrupted")]


def test_a_damaged_store_that_was_closed_cleanly_is_not_checked_on_open(tmp_path):
    store = _interrupted_store(tmp_path / "bench.db")
    with Store(store) as settled:
        settled.set_status(1, "completed")
    _damage_a_sample_page(store)
    with Store(store) as opened:  # no interrupted run: the cost of a check is not paid on every open
        assert interrupted_runs(opened._db.raw, str(store)) == []


def test_an_interrupted_healthy_store_passes_the_check_and_is_appended_to(tmp_path, capsys, caplog):
    store = tmp_path / "bench.db"
    process = subprocess.Popen(
        [BENCH, "run", str(QUICK), "--sim", "--store", str(store), "--no-progress", "--speed-factor", "60"],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    wait_for_samples(store, process, 6, timeout_s=120.0)
    process.send_signal(signal.SIGKILL)
    process.wait(30)
    with Store(store, read_only=True) as reader:
        (run,) = reader.runs()
        assert run.status == "interrupted" and run.n_samples >= 6
        before = {s.step_index: s.values for s in reader.samples(run.id)}
    caplog.set_level(logging.INFO, logger="bench.store.recovery")
    assert main(["resume", "1", "--store", str(store), "--no-progress"]) == 0
    capsys.readouterr()
    checks = [r.getMessage() for r in caplog.records if r.name == "bench.store.recovery"]
    assert len(checks) == 1 and checks[0].startswith(
        f"store {store}: not closed cleanly (run 1 interrupted); integrity check ok in "
    ), checks
    with Store(store, read_only=True) as reader:
        (run,) = reader.runs()
        after = {s.step_index: s.values for s in reader.samples(run.id)}
    assert run.status == "completed" and len(after) == 15
    assert all(after[step] == values for step, values in before.items())  # appended, nothing changed
    caplog.clear()
    assert main(["run", str(QUICK), "--sim", "--store", str(store), "--no-progress"]) == 0  # closed cleanly: no check
    capsys.readouterr()
    assert not [r for r in caplog.records if r.name == "bench.store.recovery"]


def test_the_window_reports_a_damaged_store_and_runs_nothing(window, tmp_path):
    from gui_support import RUN_TIMEOUT_S, wait_for

    from bench.gui.campaign_panel import EXAMPLES

    store = _interrupted_store(tmp_path / "bench.db")  # the window's store
    _damage_a_sample_page(store)
    before = store.read_bytes()
    window.campaign_panel.choose_file(EXAMPLES / "iso9283_pose_quick.toml")
    window.campaign_panel.start()
    wait_for(lambda: window.campaign_panel.worker is None, RUN_TIMEOUT_S, "the worker to give up")
    assert f"store {store}: not closed cleanly (run 1 interrupted) and damaged: integrity: " in window.log.toPlainText()
    assert store.read_bytes() == before
