"""One owner per run: a run is owned by the live process that drives it; a second resume of a live run is refused
naming the owner and leaves the run alone; a run whose owner died reads as ``interrupted`` and resumes."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import time
from pathlib import Path

import pytest
from cli_runs import QUICK, STATION, start_station_run, wait_for_samples

from bench.cli import main
from bench.store import INTERRUPTED, RunOwned, Store
from bench.store.ownership import STALE_AFTER_S, lock_path, owner_of


def _runs_json(store, capsys) -> list[dict]:
    capsys.readouterr()
    assert main(["runs", "--store", str(store), "--json"]) == 0
    return [json.loads(line) for line in capsys.readouterr().out.splitlines()]


def test_a_second_resume_of_a_live_run_is_refused_naming_the_owner_and_the_run_completes(tmp_path, capsys):
    store = tmp_path / "b.db"
    process = start_station_run(store, "60", stdin=subprocess.PIPE)
    try:
        wait_for_samples(store, process, 1)
        process.send_signal(signal.SIGINT)  # it pauses at the next checkpoint and waits for our answer on stdin
        (run,) = _runs_json(store, capsys)
        host = socket.gethostname()
        assert run["status"] == "running"
        assert run["reason"].startswith(f"owned by pid {process.pid} on {host} since ")
        with Store(store) as opened:
            before = opened.stored_rows(run["id"]).fetchall()
        assert (
            main(["resume", str(run["id"]), "--store", str(store), "--station", str(STATION), "--sim", "--no-progress"])
            == 1
        )
        err = capsys.readouterr().err.splitlines()
        assert len(err) == 1 and err[0].startswith(
            f"bench: error: run {run['id']}: owned by a live process, pid {process.pid} on {host} since "
        )
        assert err[0].endswith(f"left untouched (wait for it to end, or stop it: kill -TERM {process.pid} on {host})")
        with Store(store) as opened:  # the refused resume wrote nothing
            assert opened.stored_rows(run["id"]).fetchall()[: len(before)] == before
            assert opened.run(run["id"]).status == "running"
        out, err_text = process.communicate("r\n", timeout=120)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 0, err_text
    assert "paused: [r]esume" in err_text and "DuplicateSample" not in err_text
    (run,) = _runs_json(store, capsys)
    assert (run["status"], run["n_samples"], run["reason"]) == ("completed", 15, None)
    assert not lock_path(store, run["id"]).exists()  # a settled run leaves no lock file behind


def test_a_killed_run_reads_as_interrupted_and_resumes(tmp_path, capsys):
    store = tmp_path / "b.db"
    process = start_station_run(store, "300", stdin=subprocess.PIPE)
    wait_for_samples(store, process, 2)
    os.kill(process.pid, signal.SIGKILL)
    process.communicate(timeout=30)
    (run,) = _runs_json(store, capsys)
    assert run["status"] == INTERRUPTED
    assert run["reason"].startswith(f"its owner (pid {process.pid} on {socket.gethostname()} since ")
    assert run["reason"].endswith(f") is gone; next: bench resume {run['id']}")
    assert main(["runs", "--store", str(store)]) == 0
    assert f" {INTERRUPTED} " in capsys.readouterr().out
    assert (
        main(["resume", str(run["id"]), "--store", str(store), "--station", str(STATION), "--sim", "--no-progress"])
        == 0
    )
    (run,) = _runs_json(store, capsys)
    assert (run["status"], run["n_samples"]) == ("completed", 15)
    assert not lock_path(store, run["id"]).exists()


def _started(store: Store) -> int:
    return store.start_run(protocol_name="iso9283_pose", protocol_version="1", robot="pkm5", config={})


def test_within_one_process_a_second_store_sees_the_owner_and_cannot_claim(tmp_path):
    # the desktop app browses the store while its own worker drives a run: flock locks belong to the open file
    path = tmp_path / "b.db"
    with Store(path) as driver:
        run_id = _started(driver)
        with Store(path) as browser:
            assert browser.run(run_id).status == "running"
            assert browser.run(run_id).reason.startswith(f"owned by pid {os.getpid()} on ")
            with pytest.raises(RunOwned, match=f"run {run_id}: owned by a live process, pid {os.getpid()} on "):
                browser.claim(run_id)
            assert driver.run(run_id).status == "running"  # the failed claim dropped nobody's lock
            assert owner_of(path, run_id).alive
    with Store(path) as later:
        record = later.run(run_id)
        assert (record.status, record.reason) == (INTERRUPTED, f"no process owns it; next: bench resume {run_id}")
        later.claim(run_id)
        assert later.run(run_id).status == "running"
    assert not lock_path(path, run_id).exists()


def test_an_owner_on_another_host_is_alive_while_its_heartbeat_is_fresh(tmp_path):
    path = tmp_path / "b.db"
    with Store(path) as store:
        run_id = _started(store)
    lock = lock_path(path, run_id)
    lock.write_text(json.dumps({"pid": 4242, "host": "other-host", "since_utc": "2026-12-01T10:00:00+00:00"}))
    with Store(path) as store:
        assert (store.run(run_id).status, store.run(run_id).reason) == (
            "running",
            "owned by pid 4242 on other-host since 2026-12-01T10:00:00 UTC",
        )
        stale = time.time() - STALE_AFTER_S - 1
        os.utime(lock, (stale, stale))
        assert (store.run(run_id).status, store.run(run_id).reason) == (
            INTERRUPTED,
            f"its owner (pid 4242 on other-host since 2026-12-01T10:00:00 UTC) is gone; next: bench resume {run_id}",
        )


def test_a_store_in_memory_is_owned_by_its_process(tmp_path):
    with Store(":memory:") as store:
        run_id = _started(store)
        assert store.claim(run_id) is None and store.run(run_id).status == "running"


def test_bench_runs_keeps_its_columns_aligned_for_a_long_bench_name(tmp_path, capsys):
    store_path = tmp_path / "b.db"
    with Store(store_path, bench="delta4-laser-grid-bench-2") as store:
        store.set_status(_started(store), "completed")
    assert main(["runs", "--store", str(store_path)]) == 0
    header, row = capsys.readouterr().out.splitlines()
    assert row.index("delta4-laser-grid-bench-2") == header.index("bench")
    assert row.index("iso9283_pose v1") == header.index("protocol") and row.index("completed") == header.index("status")
