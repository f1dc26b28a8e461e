"""``bench sync`` with producer processes (:mod:`bench.store.lab_batches`): the local file read and formatted in
processes of their own while the batches are sent. Every sample still lands once, byte for byte; a producer that
fails or is killed mid-run leaves whole batches only, and the next sync sends the rest once."""

from __future__ import annotations

import os
import signal
import sqlite3
import uuid
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

psycopg = pytest.importorskip("psycopg", reason='the lab store needs psycopg 3 (pip install "psycopg[binary]")')

from postgres_support import lab_server, lab_url, make_store  # noqa: E402, F401  (fixtures)
from test_store_sync import local_checksums, server_state  # noqa: E402

from bench.cli import main  # noqa: E402
from bench.store import Store  # noqa: E402
from bench.store.lab import LabStoreError, sync_store  # noqa: E402


def _producers() -> list[int]:
    """The pids of this process's producer children (``python -m bench.store.lab_batches``)."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                parent = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
                command = (entry / "cmdline").read_bytes()
            except OSError:
                continue
            if parent == os.getpid() and b"bench.store.lab_batches" in command:
                found.append(int(entry.name))
    return found


def test_producers_send_every_sample_once_byte_for_byte(tmp_path, lab_url):
    path = make_store(tmp_path / "p.db", "bench-p", [1000, 700, 301])
    with Store(path) as store:  # awkward text and a sample without pose, cycle or values, as the sync meets them
        store.add_sample(2, 5000, kind="grid_hit", values={"x_mm": 0.1 + 0.2}, pose="P\t1\\n", t_s=1e-300)
        store.add_sample(2, 5001, kind="grid_hit", values={}, t_s=5e-324, raw={"path": "C:\\bench"})
        result = sync_store(store, lab_url, batch_size=128, producers=2)
    assert result.samples_sent == 2003
    assert server_state(lab_url) == (2003, 2003, local_checksums(path))
    with psycopg.connect(lab_url) as conn:  # the typed columns as the in-thread formatting fills them
        assert conn.execute("SELECT count(*) FROM bench.samples WHERE x_mm IS NULL").fetchone()[0] == 1
        assert conn.execute("SELECT x_mm FROM bench.samples WHERE step_index = 5000").fetchone()[0] == 0.1 + 0.2


def test_producers_send_only_the_steps_a_partly_synced_run_lacks(tmp_path, lab_url):
    path = make_store(tmp_path / "h.db", "bench-h", [900, 400])
    with Store(path) as store:
        sync_store(store, lab_url, batch_size=100, producers=0)
    with psycopg.connect(lab_url, autocommit=True) as conn:  # every third step of the first run lost on the server
        conn.execute(
            "DELETE FROM bench.samples WHERE run_uuid = (SELECT uuid FROM bench.runs WHERE local_id = 1)"
            " AND step_index % 3 = 0"
        )
        lost = 900 - conn.execute("SELECT count(*) FROM bench.samples").fetchone()[0] + 400
    with Store(path) as store:
        assert sync_store(store, lab_url, batch_size=100, producers=2).samples_sent == lost == 300
    assert server_state(lab_url) == (1300, 1300, local_checksums(path))


def test_a_producer_failing_mid_run_leaves_whole_batches_and_the_next_sync_resumes(tmp_path, lab_url):
    path = make_store(tmp_path / "f.db", "bench-f", [2000])
    db = sqlite3.connect(path)
    good = db.execute("SELECT values_json FROM samples WHERE step_index = 2501").fetchone()[0]
    with db:  # a sample the producer cannot read (its values_json is not JSON): it stops mid-run
        db.execute("UPDATE samples SET values_json = '{broken' WHERE step_index = 2501")
    with Store(path) as store, pytest.raises(LabStoreError, match="the process reading .* stopped .*malformed JSON"):
        sync_store(store, lab_url, batch_size=200, producers=1)
    held, distinct, _ = server_state(lab_url)
    assert held == distinct and held % 200 == 0 and held <= 1200  # whole batches before step 2501 only
    with db:
        db.execute("UPDATE samples SET values_json = ? WHERE step_index = 2501", (good,))
    db.close()
    with Store(path) as store:
        assert sync_store(store, lab_url, batch_size=200, producers=1).samples_sent == 2000 - held
    assert server_state(lab_url) == (2000, 2000, local_checksums(path))


def test_a_producer_killed_mid_run_is_one_line_and_the_next_sync_resumes(tmp_path, lab_url):
    path = make_store(tmp_path / "k.db", "bench-k", [3000, 3000])
    killed = []

    def kill_a_producer(line: str) -> None:  # after the first batch committed
        if not killed:
            killed.extend(_producers())
            os.kill(killed[0], signal.SIGKILL)

    with (
        Store(path) as store,
        pytest.raises(LabStoreError, match=r"the process reading .* stopped \(killed by signal 9"),
    ):
        sync_store(store, lab_url, batch_size=100, producers=2, progress=kill_a_producer)
    assert len(killed) == 2 and _producers() == []  # both ended: the killed one and the other, by the sync
    held, distinct, _ = server_state(lab_url)
    assert held == distinct and held % 100 == 0 and 100 <= held < 6000
    with Store(path) as store:
        assert sync_store(store, lab_url, batch_size=100, producers=2).samples_sent == 6000 - held
    assert server_state(lab_url) == (6000, 6000, local_checksums(path))


def test_bench_sync_producers_option(tmp_path, lab_url, capsys):
    path = make_store(tmp_path / "c.db", "bench-c", [500, 300])
    assert main(["sync", "--store", str(path), "--to", lab_url, "--batch", "100", "--producers", "1"]) == 0
    assert "800 new samples" in capsys.readouterr().out
    assert server_state(lab_url) == (800, 800, local_checksums(path))
    assert main(["sync", "--store", str(path), "--to", lab_url, "--producers", "3"]) == 2
    assert (
        capsys.readouterr().err.strip().splitlines()[-1] == "bench: error: --producers 3: expected a number from 0 to 2"
    )


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.integers(0, 120), st.integers(1, 40))
def test_step_marks_cut_a_run_into_batches_of_every_sample_once(tmp_path, n, every):
    path = make_store(
        tmp_path / f"m{uuid.uuid4().hex}.db", "bench-m", [n, 7]
    )  # steps 1, 3, 5, ...; a second run beside
    with Store(path) as store:
        marks = store.step_marks(1, every)
        assert marks == [2 * i + 1 for i in range(0, n, every)]
        bounds = [*marks[1:], None]
        batches = [
            [row[0] for row in store.stored_rows(1, after - 1 if i else -1, before_step=before)]
            for i, (after, before) in enumerate(zip(marks, bounds))
        ]
    assert [step for batch in batches for step in batch] == [2 * i + 1 for i in range(n)]
    assert all(len(batch) == every for batch in batches[:-1]) and 0 < len(batches[-1]) <= every if n else not batches


def test_a_malformed_values_json_stops_a_sync_in_this_thread_in_one_line(tmp_path, lab_url, capsys):
    """The sync's own thread formatting (no producer): the damaged sample is named by its step, exit 1, no
    traceback, whole batches before it kept."""
    path = make_store(tmp_path / "m.db", "bench-m", [1000])
    db = sqlite3.connect(path)
    with db:
        db.execute("UPDATE samples SET values_json = '{broken' WHERE step_index = 701")
    db.close()
    capsys.readouterr()
    assert main(["sync", "--store", str(path), "--to", lab_url, "--batch", "200", "--producers", "0"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert "Traceback" not in "\n".join(err)
    assert "sample at step 701: its values_json is malformed JSON" in err[-1], err
    held, distinct, _ = server_state(lab_url)
    assert held == distinct and held % 200 == 0 and held <= 800
