"""``bench sync`` into a real PostgreSQL server: idempotent, resumable after SIGKILL and a server restart, one-line
errors, lab-wide ``bench runs``. The server comes from ``postgres_support`` (skips with the reason when none)."""

from __future__ import annotations

import hashlib
import json
import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest

psycopg = pytest.importorskip("psycopg", reason='the lab store needs psycopg 3 (pip install "psycopg[binary]")')

from cli_lines import one_error_line as _one_error_line  # noqa: E402
from postgres_support import PASSWORD, Cluster, lab_server, lab_url, make_store  # noqa: E402, F401  (fixtures)

from bench.cli import main  # noqa: E402
from bench.store import Store  # noqa: E402
from bench.store.lab import LAB_SCHEMA_VERSION, LabServerBusy, LabStore, rows_checksum, sync_store  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def local_checksums(path: Path) -> dict[str, str]:
    with Store(path) as store:
        return {r.uuid: rows_checksum(store.stored_rows(r.id)) for r in store.runs()}


def server_state(url: str) -> tuple[int, int, dict[str, str]]:
    """(samples on the server, distinct (run, step) keys, checksum per run)."""
    with LabStore(url) as lab:
        total, distinct = lab.query("SELECT count(*), count(DISTINCT (run_uuid, step_index)) FROM bench.samples")[0]
        return total, distinct, {r.uuid: lab.checksum(r.uuid) for r in lab.runs()}


def file_digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _kill_after_batches(sync: subprocess.Popen, batches: int) -> None:
    """SIGKILL a running ``bench sync`` once it has reported ``batches`` committed batches on stderr."""
    seen = 0
    for line in sync.stderr:
        seen += line.startswith("sync: run ")
        if seen == batches:
            os.kill(sync.pid, signal.SIGKILL)
            break
    sync.wait(timeout=30)


def test_sync_twice_sends_nothing_twice(tmp_path, lab_url):
    path = make_store(tmp_path / "a.db", "bench-a", [250, 40])
    with Store(path) as store:
        first = sync_store(store, lab_url, batch_size=100)
        second = sync_store(store, lab_url, batch_size=100)
    assert (first.runs, first.calibrations, first.samples_sent) == (2, 1, 290)
    assert (second.runs, second.samples_sent) == (2, 0)
    assert server_state(lab_url) == (290, 290, local_checksums(path))
    with Store(path) as store:  # a sample added and a status settled later travel on the next sync
        store.add_sample(2, 500, values={"x_mm": 1.0}, t_s=99.0)
        store.set_status(2, "aborted", "operator abort")
        assert sync_store(store, lab_url).samples_sent == 1
    assert server_state(lab_url) == (291, 291, local_checksums(path))
    with LabStore(lab_url) as lab:
        runs = {r.id: r for r in lab.runs()}
        assert (runs[2].status, runs[2].reason, runs[2].bench, runs[1].n_samples) == (
            "aborted",
            "operator abort",
            "bench-a",
            250,
        )
        assert runs[2].n_samples == 41
        assert lab.query("SELECT name, params_json FROM bench.calibrations") == [
            ("mouse", '{"mm_per_count": 0.03175, "nominal": true}')
        ]


def test_awkward_text_arrives_byte_for_byte(tmp_path, lab_url):
    path = tmp_path / "t.db"
    with Store(path, bench="bench-\\t") as store:
        run_id = store.start_run(protocol_name="p", protocol_version="1", robot="pkm5", config={"note": "a\tb"})
        store.add_sample(
            run_id,
            0,
            kind="grid_hit",
            values={"x_mm": 0.1 + 0.2},
            pose="P\t1\\n\nend\r",
            t_s=1e-300,
            raw={"path": "C:\\bench\\new", "text": "tab\there"},
        )
        store.add_sample(run_id, 1, kind="grid_hit", values={}, pose=None, cycle=None, t_s=5e-324, raw=None)
        sync_store(store, lab_url)
    assert server_state(lab_url) == (2, 2, local_checksums(path))
    with LabStore(lab_url) as lab:
        assert lab.query("SELECT pose, raw_json FROM bench.samples ORDER BY step_index") == [
            ("P\t1\\n\nend\r", '{"path": "C:\\\\bench\\\\new", "text": "tab\\there"}'),
            (None, None),
        ]
        assert lab.check_samples() == ([], [])  # each checksum arrived as stored, and checks on the server


def test_sync_killed_midway_then_resumed_has_every_sample_once(tmp_path, lab_url):
    path = make_store(tmp_path / "b.db", "bench-b", [6000, 6000, 3000])
    before = file_digest(path)
    writer = subprocess.Popen(
        [sys.executable, "-m", "bench.cli", "sync", "--store", str(path), "--to", lab_url, "--batch", "500"],
        cwd=ROOT,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    _kill_after_batches(writer, 7)
    assert writer.returncode == -signal.SIGKILL
    partial, distinct, _ = server_state(lab_url)
    assert 3500 <= partial < 15000 and distinct == partial
    with Store(path) as store:
        resumed = sync_store(store, lab_url, batch_size=500)
    assert resumed.samples_sent == 15000 - partial
    assert server_state(lab_url) == (15000, 15000, local_checksums(path))
    assert file_digest(path) == before  # sync only reads the local file


def test_server_restart_mid_sync_is_retried(tmp_path, lab_server, lab_url):
    if not isinstance(lab_server, Cluster):
        pytest.skip("BENCH_TEST_POSTGRES is not ours to restart")
    path = make_store(tmp_path / "c.db", "bench-c", [2500, 1500])  # two runs: both lanes cut off, counted once
    restarted = []

    def progress(line: str) -> None:
        if line.startswith("sync: run ") and not restarted:
            lab_server.stop("fast")
            restarted.append(threading.Timer(1.0, lab_server.start))
            restarted[0].start()

    with Store(path) as store:
        result = sync_store(store, lab_url, batch_size=1000, retries=5, retry_wait_s=0.5, progress=progress)
    restarted[0].join()
    assert result.samples_sent == 4000
    assert server_state(lab_url) == (4000, 4000, local_checksums(path))


def test_bad_url_credentials_and_server_are_one_line_each(tmp_path, lab_url, capsys):
    path = make_store(tmp_path / "d.db", "bench-d", [10])
    before = file_digest(path)
    assert main(["sync", "--store", str(path), "--to", "mysql://bench@localhost/lab"]) == 2
    assert _one_error_line(capsys) == (
        "bench: error: --to mysql://bench@localhost/lab: expected a postgresql://USER:PASSWORD@HOST/DBNAME URL"
    )
    assert main(["sync", "--store", str(path), "--to", "postgresql://bench@/lab?colour=blue"]) == 2
    line = _one_error_line(capsys)  # libpq's own words follow: "invalid URI query parameter" in libpq 15
    assert (
        line.startswith("bench: error: --to postgresql://bench@/lab?colour=blue: not a valid PostgreSQL URL (invalid ")
        and '"colour"' in line
    )
    wrong = lab_url.replace(PASSWORD, "not-the-password") if PASSWORD in lab_url else lab_url + "&password=nope"
    assert main(["sync", "--store", str(path), "--to", wrong, "--retries", "0"]) == 1
    line = _one_error_line(capsys)
    assert "bad credentials (" in line and "password authentication failed" in line and "not-the-password" not in line
    assert (
        main(
            [
                "sync",
                "--store",
                str(path),
                "--to",
                "postgresql://bench:pw@127.0.0.1:9/lab?connect_timeout=2",
                "--retries",
                "0",
            ]
        )
        == 1
    )
    assert _one_error_line(capsys).startswith(
        "bench: error: lab store postgresql://bench:***@127.0.0.1:9/lab?connect_timeout=2: server unreachable ("
    )
    assert file_digest(path) == before


def test_newer_server_schema_is_refused(tmp_path, lab_url, capsys):
    path = make_store(tmp_path / "e.db", "bench-e", [10])
    assert main(["sync", "--store", str(path), "--to", lab_url]) == 0
    with psycopg.connect(lab_url, autocommit=True) as conn:
        conn.execute("UPDATE bench.schema_version SET version = 7")
    capsys.readouterr()
    assert main(["sync", "--store", str(path), "--to", lab_url]) == 1
    assert _one_error_line(capsys).endswith(
        f"server schema version 7 is newer than this bench's ({LAB_SCHEMA_VERSION}); upgrade bench to sync"
    )


def test_lab_wide_runs_with_filters(tmp_path, lab_url, capsys):
    for bench, robot in (("bench-a", "pkm5"), ("bench-b", "delta4")):
        path = make_store(tmp_path / f"{bench}.db", bench, [5, 3], robot=robot)
        assert main(["sync", "--store", str(path), "--to", lab_url]) == 0
    capsys.readouterr()
    assert main(["runs", "--store", lab_url, "--json"]) == 0
    listed = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert sorted((r["bench"], r["robot"], r["id"], r["n_samples"]) for r in listed) == [
        ("bench-a", "pkm5", 1, 5),
        ("bench-a", "pkm5", 2, 3),
        ("bench-b", "delta4", 1, 5),
        ("bench-b", "delta4", 2, 3),
    ]
    assert main(["runs", "--store", lab_url, "--json", "--bench", "bench-b", "--robot", "delta4"]) == 0
    assert len(capsys.readouterr().out.splitlines()) == 2
    assert main(["runs", "--store", lab_url, "--robot", "pkm5", "--since", "2999-01-01"]) == 0
    assert capsys.readouterr().out.splitlines()[1:] == []
    assert main(["runs", "--store", lab_url, "--since", "last tuesday"]) == 2
    assert _one_error_line(capsys) == "bench: error: --since last tuesday: expected an ISO date such as 2026-11-01"


def test_benches_sync_at_once_through_a_kill_and_a_server_restart(tmp_path, lab_server, lab_url):
    """The issue's acceptance, scaled to 4 benches: one is SIGKILLed mid-sync, the server is restarted while the
    others sync (they reconnect), the killed one syncs again: every sample once, checksums equal per run."""
    if not isinstance(lab_server, Cluster):
        pytest.skip("BENCH_TEST_POSTGRES is not ours to restart")
    paths = [make_store(tmp_path / f"bench{i}.db", f"bench-{i}", [1500, 500]) for i in range(4)]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}

    def sync(path, **streams):
        return subprocess.Popen(
            [
                sys.executable,
                "-m",
                "bench.cli",
                "sync",
                "--store",
                str(path),
                "--to",
                lab_url,
                "--batch",
                "100",
                "--retries",
                "6",
            ],
            cwd=ROOT,
            env=env,
            text=True,
            **streams,
        )

    victim = sync(paths[0], stderr=subprocess.PIPE)
    others = [sync(p, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for p in paths[1:]]
    _kill_after_batches(victim, 3)
    lab_server.stop("fast")
    restart = threading.Timer(1.0, lab_server.start)
    restart.start()
    restart.join()
    assert [p.wait(timeout=120) for p in others] == [0, 0, 0]
    assert victim.returncode == -signal.SIGKILL
    with Store(paths[0]) as store:
        sync_store(store, lab_url)
    expected = {uuid: digest for p in paths for uuid, digest in local_checksums(p).items()}
    assert server_state(lab_url) == (8000, 8000, expected)


def test_two_syncs_of_one_file_at_once_store_every_sample_once(tmp_path, lab_url):
    """The second sync meets steps the first one committed after it asked (COPY's key violation): it skips them."""
    path = make_store(tmp_path / "f.db", "bench-f", [4000, 4000])
    with Store(path) as store:
        sync_store(store, lab_url, batch_size=10_000)  # schema and runs in place; then the samples are removed
    with psycopg.connect(lab_url, autocommit=True) as conn:
        conn.execute("DELETE FROM bench.samples")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    syncs = [
        subprocess.Popen(
            [sys.executable, "-m", "bench.cli", "sync", "--store", str(path), "--to", lab_url, "--batch", "250"],
            cwd=ROOT,
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
        )
        for _ in range(2)
    ]
    outs = [p.communicate(timeout=120)[0] for p in syncs]
    assert [p.returncode for p in syncs] == [0, 0]
    sent = [int(out.split(" new samples")[0].rsplit(" ", 1)[1]) for out in outs]
    assert sum(sent) == 8000
    assert server_state(lab_url) == (8000, 8000, local_checksums(path))


def _limited_role(lab_url: str, limit: int) -> str:
    """A lab URL for a role of ``limit`` connections at most (superusers have no limit), allowed to sync."""
    role = f"crowd_{abs(hash(lab_url)) % 10**8}"
    with psycopg.connect(lab_url, autocommit=True) as admin:
        admin.execute(f"CREATE ROLE {role} LOGIN PASSWORD 'crowd-pw' CONNECTION LIMIT {limit}")
        admin.execute("CREATE SCHEMA IF NOT EXISTS bench")
        admin.execute(f"GRANT USAGE, CREATE ON SCHEMA bench TO {role}")
        admin.execute(f"GRANT ALL ON ALL TABLES IN SCHEMA bench TO {role}")
        admin.execute(f"GRANT ALL ON ALL SEQUENCES IN SCHEMA bench TO {role}")
    return lab_url.replace(f"bench:{PASSWORD}@", f"{role}:crowd-pw@")


def test_a_crowded_server_makes_a_sync_wait_for_a_slot_not_fail(tmp_path, lab_url):
    first = make_store(tmp_path / "first.db", "bench-first", [10])
    with Store(first) as store:
        sync_store(store, lab_url)  # the schema exists before the limited role syncs
    url = _limited_role(lab_url, 1)
    path = make_store(tmp_path / "crowd.db", "bench-crowd", [300, 200])
    holder = psycopg.connect(url)  # another bench holds the role's only slot
    waiting, lines = threading.Event(), []

    def progress(line: str) -> None:
        lines.append(line)
        if "server busy, no connection slot free" in line:
            waiting.set()

    def release() -> None:
        waiting.wait(timeout=120)
        holder.close()

    releaser = threading.Thread(target=release)
    releaser.start()
    with Store(path, read_only=True) as store:
        result = sync_store(store, url, batch_size=100, retry_wait_s=0.05, progress=progress)
    releaser.join()
    assert waiting.is_set() and result.samples_sent == 500  # it waited, then sent through the one slot
    assert sum("waiting for a free connection" in line for line in lines) == 1
    total, distinct, checksums = server_state(lab_url)
    assert (total, distinct) == (510, 510)
    assert checksums == {**local_checksums(first), **local_checksums(path)}


def test_a_busy_server_past_the_wait_is_one_line(tmp_path, lab_url, capsys):
    url = _limited_role(lab_url, 0)
    path = make_store(tmp_path / "never.db", "bench-never", [10])
    with (
        Store(path, read_only=True) as store,
        pytest.raises(
            LabServerBusy,
            match=r"server busy, no connection slot "
            r"free \(.*too many connections",
        ),
    ):
        sync_store(store, url, retry_wait_s=0.01, busy_wait_s=0.2)
