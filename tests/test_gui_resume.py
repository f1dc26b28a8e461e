"""A resume from the window is refused or accepted exactly as ``bench resume`` refuses or accepts it (issue 32): both
hold the run with :func:`bench.launch.resuming`, so opening the rig writes no new calibration and a refused resume
writes nothing; the run is released again, so the command line can take it while the window stays open."""

from __future__ import annotations

import pytest

pytest.importorskip("PySide6")

from gui_support import RUN_TIMEOUT_S, wait_for

from bench.cli import main
from bench.gui.campaign_panel import EXAMPLES
from bench.store import Store


def test_a_resume_the_cli_refuses_for_its_calibrations_is_refused_alike_in_the_window_and_writes_nothing(
    window, tmp_path, capsys
):
    store_path = str(tmp_path / "bench.db")
    run = ["run", str(EXAMPLES / "iso9283_pose_quick.toml"), "--sim", "--speed-factor", "20000"]
    assert main([*run, "--store", store_path, "--no-progress"]) == 0
    with Store(store_path) as store:
        (record,) = store.runs()
        (used,) = [store.calibration_by_id(i) for i in record.calibration_ids]
        # the calibration in force changes after the run: a resume would have to put in force a third version
        store.add_calibration(used.name, {**used.params, "mm_per_count": 2 * used.params["mm_per_count"]})
        before = [(c.name, c.version) for c in store.calibrations()]
    capsys.readouterr()
    assert main(["resume", str(record.id), "--store", store_path, "--no-progress"]) == 2
    refusal = capsys.readouterr().err.strip().removeprefix("bench: error: ")
    assert refusal.startswith(f"run {record.id}: calibration {used.name!r} in force would be a new version"), refusal

    panel = window.campaign_panel
    panel.start([record.id])
    wait_for(lambda: panel.worker is None, RUN_TIMEOUT_S, "the refused resume to end")
    assert panel.last_outcome == f"not started: {refusal}"
    with Store(store_path) as store:
        assert [(c.name, c.version) for c in store.calibrations()] == before  # nothing written
        assert store.run(record.id).status == "completed"
    # released: the command line meets the same refusal, not "owned by" the window's process
    assert main(["resume", str(record.id), "--store", store_path, "--no-progress"]) == 2
    assert capsys.readouterr().err.strip().removeprefix("bench: error: ") == refusal
