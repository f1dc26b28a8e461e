"""The store file is always a complete store: the write-ahead log is checkpointed at every checkpoint step and at
the end of every run segment, so the ``.db`` file alone (a backup, a copy after a crash) holds every sample
committed before the last checkpoint; ``bench backup`` makes a consistent copy while a run is writing."""

from __future__ import annotations

import shutil
import signal
import subprocess
from pathlib import Path

from cli_runs import BENCH, wait_for_samples

from bench.cli import main
from bench.store import Store

ROOT = Path(__file__).resolve().parents[1]
QUICK = ROOT / "examples" / "iso9283_pose_quick.toml"


def _values(path: Path) -> dict[int, dict]:
    with Store(path) as store:
        (run,) = store.runs()
        return {s.step_index: s.values for s in store.samples(run.id)}


def _start_and_wait(store: Path, at_least: int) -> subprocess.Popen:
    process = subprocess.Popen([BENCH, "run", str(QUICK), "--store", str(store), "--no-progress",
                                "--speed-factor", "60"], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                               stderr=subprocess.PIPE, text=True)
    wait_for_samples(store, process, at_least, timeout_s=120.0)
    return process


def test_the_db_file_alone_holds_every_sample_up_to_the_last_checkpoint_even_after_kill_9(tmp_path):
    store = tmp_path / "b.db"
    process = _start_and_wait(store, 6)  # past the first cycle's checkpoint (5 poses a cycle)
    live_copy = tmp_path / "copy-live.db"
    shutil.copyfile(store, live_copy)  # the .db file only, taken while the run writes
    process.send_signal(signal.SIGKILL)
    process.wait(30)
    crash_copy = tmp_path / "copy-crash.db"
    shutil.copyfile(store, crash_copy)  # the .db file only, after the crash
    stored = _values(store)
    for copy in (live_copy, crash_copy):
        values = _values(copy)
        assert len(values) >= 5, copy  # the first cycle, committed before its checkpoint
        assert all(stored[step] == row for step, row in values.items())


def test_a_clean_run_leaves_a_complete_db_file(tmp_path, capsys):
    store = tmp_path / "b.db"
    assert main(["run", str(QUICK), "--store", str(store), "--no-progress"]) == 0
    capsys.readouterr()
    alone = tmp_path / "alone.db"
    shutil.copyfile(store, alone)
    assert len(_values(alone)) == 15 and _values(alone) == _values(store)


def test_bench_backup_copies_a_store_while_a_run_writes(tmp_path, capsys):
    store = tmp_path / "b.db"
    process = _start_and_wait(store, 3)
    try:
        assert main(["backup", str(tmp_path / "backup.db"), "--store", str(store)]) == 0
    finally:
        process.wait(120)
    assert capsys.readouterr().out.strip() == str(tmp_path / "backup.db")
    backup, final = _values(tmp_path / "backup.db"), _values(store)
    assert len(backup) >= 3 and all(final[step] == row for step, row in backup.items())
    assert main(["backup", str(tmp_path / "backup.db"), "--store", str(store)]) == 2  # never overwrites
    assert "exists, expected a new file name" in capsys.readouterr().err


def test_export_into_a_missing_folder_and_a_header_only_table_are_one_line(tmp_path, capsys):
    store = tmp_path / "b.db"
    assert main(["run", str(QUICK), "--store", str(store), "--no-progress"]) == 0
    capsys.readouterr()
    missing = tmp_path / "nope" / "run.csv"
    assert main(["export", "1", "--store", str(store), "--out", str(missing)]) == 2
    assert capsys.readouterr().err.strip() == (f"bench: error: export: folder {missing.parent} does not exist, "
                                               "expected an existing folder")
    table = tmp_path / "run.csv"
    assert main(["export", "1", "--store", str(store), "--out", str(table)]) == 0
    header = tmp_path / "header.csv"
    header.write_text(table.read_text().splitlines()[0] + "\n")
    capsys.readouterr()
    assert main(["analyze", "iso9283", str(header)]) == 2
    assert capsys.readouterr().err.strip() == f"bench: error: {header}: no rows, expected at least one measured pose"
