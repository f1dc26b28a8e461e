"""The store file is always a complete store: the write-ahead log is checkpointed at every checkpoint step and at
the end of every run segment, so the ``.db`` file alone (a backup, a copy after a crash) holds every sample
committed before the last checkpoint; ``bench backup`` makes a consistent copy while a run is writing."""

from __future__ import annotations

import random
import shutil
import signal
import subprocess
import time
from pathlib import Path

from cli_runs import BENCH, wait_for_samples

from bench.cli import main
from bench.store import Store
from bench.store.connection import check_store

ROOT = Path(__file__).resolve().parents[1]
QUICK = ROOT / "examples" / "iso9283_pose_quick.toml"


def _values(path: Path) -> dict[int, dict]:
    with Store(path) as store:
        (run,) = store.runs()
        return {s.step_index: s.values for s in store.samples(run.id)}


def _start_and_wait(store: Path, at_least: int) -> subprocess.Popen:
    process = subprocess.Popen(
        [BENCH, "run", str(QUICK), "--sim", "--store", str(store), "--no-progress", "--speed-factor", "60"],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
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
    assert main(["run", str(QUICK), "--sim", "--store", str(store), "--no-progress"]) == 0
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
        _, errors = process.communicate(timeout=120)
    assert process.returncode == 0, errors  # the run the backup was taken beside ended well
    assert capsys.readouterr().out.strip() == str(tmp_path / "backup.db")
    backup, final = _values(tmp_path / "backup.db"), _values(store)
    assert len(backup) >= 3 and all(final[step] == row for step, row in backup.items())
    assert main(["backup", str(tmp_path / "backup.db"), "--store", str(store)]) == 2  # never overwrites
    assert "exists, expected a new file name" in capsys.readouterr().err


def test_export_into_a_missing_folder_and_a_header_only_table_are_one_line(tmp_path, capsys):
    store = tmp_path / "b.db"
    assert main(["run", str(QUICK), "--sim", "--store", str(store), "--no-progress"]) == 0
    capsys.readouterr()
    missing = tmp_path / "nope" / "run.csv"
    assert main(["export", "1", "--store", str(store), "--out", str(missing)]) == 2
    assert capsys.readouterr().err.strip() == (
        f"bench: error: export: folder {missing.parent} does not exist, expected an existing folder"
    )
    table = tmp_path / "run.csv"
    assert main(["export", "1", "--store", str(store), "--out", str(table)]) == 0
    header = tmp_path / "header.csv"
    header.write_text(table.read_text().splitlines()[0] + "\n")
    capsys.readouterr()
    assert main(["analyze", "iso9283", str(header)]) == 2
    assert capsys.readouterr().err.strip() == f"bench: error: {header}: no rows, expected at least one measured pose"


def _live(store: Path) -> dict[int, tuple[int, dict]]:
    """The samples of the live run, read read-only the way any reader would: step -> (cycle, values)."""
    with Store(store, read_only=True) as reader:
        runs = reader.runs()
        return {s.step_index: (s.cycle, s.values) for s in reader.samples(runs[0].id)} if runs else {}


def _wait_reading(store: Path, process: subprocess.Popen, at_least: int, timeout_s: float = 120.0) -> None:
    """Wait, reading read-only, until the live run holds ``at_least`` samples (or the run has ended)."""
    deadline = time.monotonic() + timeout_s
    while process.poll() is None and time.monotonic() < deadline:
        if store.exists() and len(_live(store)) >= at_least:
            return
        time.sleep(0.02)
    assert time.monotonic() < deadline, f"no {at_least} samples within {timeout_s:g} s"


def test_copies_of_the_db_file_at_random_moments_of_a_run_hold_every_sample_before_the_last_checkpoint(tmp_path):
    """The drill: the ``.db`` file alone (no ``-wal``, no ``-shm``) copied at seeded random moments while a run
    writes, and ``bench backup`` at the moments between. A copy must open as a sound store holding every sample
    committed before the last checkpoint step the run had passed: the protocol closes each cycle with a
    Checkpoint, so once a sample of cycle c is stored, the checkpoint after cycle c - 1 is done. A backup must hold
    every sample committed when it began. Every row of either equals the finished run's."""
    protocol = tmp_path / "four_cycles.toml"
    protocol.write_text(QUICK.read_text().replace("cycles = 3", "cycles = 4"))
    store, rng = tmp_path / "b.db", random.Random(15)
    process = subprocess.Popen(
        [BENCH, "run", str(protocol), "--sim", "--store", str(store), "--no-progress", "--speed-factor", "60"],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    moments = sorted(rng.sample(range(1, 18), 8))  # after how many stored samples, then a random delay
    taken: list[tuple[Path, dict[int, dict]]] = []
    try:
        for n, at_least in enumerate(moments):
            _wait_reading(store, process, at_least)
            time.sleep(rng.uniform(0.0, 0.1))
            live = _live(store)
            copy = tmp_path / f"copy-{n}.db"
            if n % 2 == 0:
                last_cycle = max(cycle for cycle, _ in live.values())
                shutil.copyfile(store, copy)
                must_hold = {step: values for step, (cycle, values) in live.items() if cycle < last_cycle}
            else:
                with Store(store, read_only=True) as reader:
                    reader.backup_to(copy)
                must_hold = {step: values for step, (_, values) in live.items()}
            taken.append((copy, must_hold))
        assert process.wait(120) == 0, process.stderr.read()
    finally:
        if process.poll() is None:
            process.kill()
            process.wait(30)
    final = _values(store)
    assert len(final) == 20
    for copy, must_hold in taken:
        assert check_store(str(copy)) == [], copy
        with Store(copy, read_only=True) as opened:  # the run is in the file from its start
            assert [(r.id, r.protocol_name) for r in opened.runs()] == [(1, "iso9283_pose")]
        held = {step: values for step, (_, values) in _live(copy).items()}
        assert must_hold.items() <= held.items(), (copy, sorted(must_hold), sorted(held))
        assert all(final[step] == values for step, values in held.items()), copy
    plain = [len(must) for copy, must in taken[::2]]
    assert max(plain) >= 10, plain  # the drill reached copies that owe two or more checkpointed cycles
