"""A real PostgreSQL server for the lab-store tests: ``BENCH_TEST_POSTGRES`` when given, else a throwaway cluster.

The throwaway cluster is made with Debian's ``initdb``/``pg_ctl`` (``/usr/lib/postgresql/*/bin``), owned by a
non-root user (``nobody`` when the tests run as root, as in CI), listening only on a unix socket in a temporary
folder, with password (SCRAM) authentication so that bad credentials are refused as on a lab server. Each test
gets a fresh database on it. Without either, the tests skip and say why.
"""

from __future__ import annotations

import glob
import json
import os
import re
import shutil
import sqlite3
import subprocess
import tempfile
import time
import uuid
from pathlib import Path
from urllib.parse import urlsplit, urlunsplit

import pytest

from bench.store import Store
from bench.store.record_checksum import seal_run
from bench.store.sample_checksum import sample_checksum

PASSWORD = "bench-test-pw"
_ENV = "BENCH_TEST_POSTGRES"


def _bindir() -> Path | None:
    for found in sorted(glob.glob("/usr/lib/postgresql/*/bin"), key=lambda p: int(p.split("/")[-2]), reverse=True):
        if Path(found, "initdb").exists():
            return Path(found)
    initdb = shutil.which("initdb")
    return Path(initdb).parent if initdb else None


def make_store(path: Path, bench: str, samples_per_run: list[int], robot: str = "pkm5") -> Path:
    """A store of ``len(samples_per_run)`` completed runs with pose samples (bulk-inserted: one transaction), as
    the simulator would write them (used by the sync tests and ``benchmarks/bench_sync.py``)."""
    with Store(path, bench=bench) as store:
        calibration = store.ensure_calibration("mouse", {"mm_per_count": 0.03175, "nominal": True})
        run_ids = [
            store.start_run(
                protocol_name="iso9283_pose",
                protocol_version="1",
                robot=robot,
                config={"cycles": n},
                calibration_ids=[calibration.id],
                campaign="c1",
            )
            for n in samples_per_run
        ]
    db = sqlite3.connect(path)
    with db:
        for run_id, n in zip(run_ids, samples_per_run):
            db.executemany(
                "INSERT INTO samples (run_id, step_index, kind, pose, cycle, t_s, wall_utc, values_json, raw_json,"
                " checksum) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                [(run_id, *row, sample_checksum(*row)) for row in _pose_rows(run_id, n)],
            )
            db.execute("UPDATE runs SET status = 'completed', ended_utc = started_utc WHERE id = ?", (run_id,))
            seal_run(db, run_id)  # an edit by hand, sealed as bench seals its own
    db.close()  # the last connection checkpoints the WAL: the file's bytes are final
    return path


def _pose_rows(run_id: int, n: int) -> list[tuple]:
    """``n`` pose samples of run ``run_id`` as stored (step_index ... raw_json), without the run id."""
    return [
        (
            2 * i + 1,
            "pose",
            f"P{i % 5 + 1}",
            i // 5 + 1,
            i * 0.1 + 1e-9 * run_id,
            f"2026-11-02T10:00:{i % 60:02d}.000000+00:00",
            json.dumps(
                {
                    "cmd_x_mm": 110.0,
                    "cmd_y_mm": 0.0,
                    "cmd_z_mm": 320.0,
                    "x_mm": 110.0 + (i % 7) * 1e-3,
                    "y_mm": -1.3 + run_id / 7,
                    "z_mm": 318.3,
                },
                sort_keys=True,
            ),
            json.dumps({"counts": [i, -i]}) if i % 3 else None,
        )
        for i in range(n)
    ]


class Cluster:
    """A throwaway PostgreSQL cluster on a unix socket (``url``), which tests may stop and start again."""

    def __init__(self, bindir: Path) -> None:
        self.bindir = bindir
        self.root = Path(tempfile.mkdtemp(prefix="bench-pg-"))
        self.user = "nobody" if os.geteuid() == 0 else None
        if self.user:
            shutil.chown(self.root, user=self.user)
        pwfile = self.root / "pw"
        pwfile.write_text(PASSWORD + "\n")
        if self.user:
            shutil.chown(pwfile, user=self.user)
        self._call(
            "initdb",
            "-D",
            str(self.root / "data"),
            "-U",
            "bench",
            f"--pwfile={pwfile}",
            "--auth=scram-sha-256",
            "-E",
            "UTF8",
            "--locale=C",
            "--no-sync",
        )
        self.url = f"postgresql://bench:{PASSWORD}@/postgres?host={self.root}&port=5432"
        self.start()

    def _call(self, tool: str, *args: str) -> None:
        result = subprocess.run(
            [str(self.bindir / tool), *args],
            cwd=self.root,
            user=self.user,
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
        )
        if result.returncode != 0:
            raise RuntimeError(f"{tool} failed: {result.stdout}{result.stderr}")

    def start(self) -> None:
        self._call(
            "pg_ctl",
            "-D",
            str(self.root / "data"),
            "-l",
            str(self.root / "log"),
            "-w",
            "-o",
            f"-k {self.root} -c listen_addresses='' -p 5432",
            "start",
        )

    def stop(self, mode: str = "fast") -> None:
        self._call("pg_ctl", "-D", str(self.root / "data"), "-m", mode, "-w", "stop")

    def close(self) -> None:
        try:
            self.stop("immediate")
        except RuntimeError:
            pass
        shutil.rmtree(self.root, ignore_errors=True)


class External:
    """The server named by ``BENCH_TEST_POSTGRES`` (not ours to stop)."""

    def __init__(self, url: str) -> None:
        self.url = url

    def close(self) -> None:
        pass


def with_database(url: str, dbname: str) -> str:
    """``url`` pointing at database ``dbname`` instead."""
    return urlunsplit(urlsplit(url)._replace(path=f"/{dbname}"))


@pytest.fixture(scope="session")
def lab_server():
    """The PostgreSQL server of the session (see the module docstring); skips when there is none."""
    pytest.importorskip("psycopg", reason='the lab store needs psycopg 3 (pip install "psycopg[binary]")')
    if os.environ.get(_ENV):
        server = External(os.environ[_ENV])
    else:
        bindir = _bindir()
        if bindir is None:
            pytest.skip(f"no PostgreSQL server: set {_ENV}=postgresql://... or install postgresql (initdb)")
        server = Cluster(bindir)
    yield server
    server.close()


@pytest.fixture()
def lab_url(lab_server):
    """A fresh, empty database on the session's server, dropped afterwards."""
    import psycopg

    name = f"bench_test_{uuid.uuid4().hex[:12]}"
    with psycopg.connect(lab_server.url, autocommit=True) as admin:
        admin.execute(f'CREATE DATABASE "{name}"')
    yield with_database(lab_server.url, name)
    with psycopg.connect(lab_server.url, autocommit=True) as admin:
        admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')


_AUTHORIZED = re.compile(r"\[(\d+)\] LOG:  connection authorized: user=\S+ database=(\S+)(?: application_name=(\S+))?")
_DISCONNECTED = re.compile(r"\[(\d+)\] LOG:  disconnection: ")


def log_sessions(cluster: Cluster) -> None:
    """Have the server log every session's start and end from now on, for :func:`connection_peaks`
    (``log_connections`` only takes effect from the server's configuration: set, reloaded, and waited for)."""
    import psycopg

    with psycopg.connect(cluster.url, autocommit=True) as admin:
        for setting in ("log_connections", "log_disconnections"):
            admin.execute(f"ALTER SYSTEM SET {setting} = on")
        admin.execute("SELECT pg_reload_conf()")
    for _ in range(1000):  # the postmaster reloads when signalled: a new session shows it has
        with psycopg.connect(cluster.url) as probe:
            if probe.execute("SHOW log_connections").fetchone() == ("on",):
                return
        time.sleep(0.01)
    raise RuntimeError("the server did not take log_connections = on")


def connection_peaks(cluster: Cluster, dbname: str, *, wait_s: float = 60.0) -> tuple[dict[str, int], int]:
    """The most sessions each application name held at once on database ``dbname``, and the most of all of them
    at once, from the server's own log: a session counts from its "connection authorized"
    line to its "disconnection" line (paired by backend pid), in the log's order; ``application_name`` in the URL
    names a bench's sessions. A connection the server turned away ("too many clients") logs neither. Waits (up to ``wait_s``) for the sessions still ending."""
    deadline = time.monotonic() + wait_s
    while True:
        open_now: dict[str, str] = {}  # pid -> application name
        peaks: dict[str, int] = {}
        per_name: dict[str, int] = {}
        overall = 0
        for line in (cluster.root / "log").read_text(errors="replace").splitlines():
            if (authorized := _AUTHORIZED.search(line)) and authorized[2] == dbname:
                pid, name = authorized[1], authorized[3] or ""
                open_now[pid] = name
                per_name[name] = per_name.get(name, 0) + 1
                peaks[name] = max(peaks.get(name, 0), per_name[name])
                overall = max(overall, len(open_now))
            elif (ended := _DISCONNECTED.search(line)) and ended[1] in open_now:
                per_name[open_now.pop(ended[1])] -= 1
        if not open_now or time.monotonic() > deadline:
            return peaks, overall
        time.sleep(0.05)
