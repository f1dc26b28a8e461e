"""Streamed rows in the store: batches stored whole in one transaction, the StreamWriter's batching, refusals,
and every committed batch surviving a SIGKILL of the writer."""

import os
import sqlite3
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from bench.errors import ConfigError
from bench.sensors.input_event import MotionFrames
from bench.store import Store
from bench.store.streams import StreamWriter


def _run(store):
    return store.start_run(protocol_name="stream", protocol_version="1", robot="pkm5", config={})


def _frames(start, n):
    k = np.arange(start, start + n)
    return MotionFrames(k * 1.25e-4, k % 7 - 3, -(k % 5), k % 11 != 0)


def test_a_batch_is_stored_as_given(tmp_path):
    with Store(tmp_path / "s.db") as store:
        run = _run(store)
        f = _frames(0, 800)
        assert store.add_stream_rows(run, "mouse_xy", f.t_s, f.dx, f.dy, f.valid) == 800
        t, dx, dy, valid = store.stream_rows(run, "mouse_xy")
        assert store.stream_rows(run, "mouse_xz")[0].size == 0
    assert np.array_equal(t, f.t_s) and np.array_equal(dx, f.dx) and np.array_equal(dy, f.dy)
    assert np.array_equal(valid, f.valid) and (~valid).sum() == 73  # k = 0, 11, ..., 792


def test_the_writer_flushes_by_rows_and_by_age(tmp_path):
    now = [0.0]
    with Store(tmp_path / "s.db") as store:
        run = _run(store)
        writer = StreamWriter(store, run, "mouse_xy", batch_s=0.1, batch_rows=1000, clock=lambda: now[0])
        assert writer.append(_frames(0, 600)) == 0  # young and few: waits
        assert writer.append(_frames(600, 600)) == 1200  # 1200 >= 1000 rows
        assert writer.append(_frames(1200, 10)) == 0
        now[0] = 0.1
        assert writer.append(_frames(1210, 5)) == 15  # the oldest waited 0.1 s
        writer.append(_frames(1215, 3))
        writer.close()
        assert writer.committed == 1218
        t = store.stream_rows(run, "mouse_xy")[0]
    assert np.array_equal(t, np.arange(1218) * 1.25e-4)


def test_bad_rows_are_refused_and_nothing_of_the_batch_stored(tmp_path):
    with Store(tmp_path / "s.db") as store:
        run = _run(store)
        t = np.array([0.0, np.nan, 0.2])
        with pytest.raises(ConfigError, match=r"stream mouse_xy: t_s\[1\] = nan, expected a finite number"):
            store.add_stream_rows(run, "mouse_xy", t, [1, 2, 3], [0, 0, 0], [True] * 3)
        with pytest.raises(ConfigError, match="expected one length"):
            store.add_stream_rows(run, "mouse_xy", [0.0, 1.0], [1], [0, 0], [True, True])
        with pytest.raises(ConfigError, match=f"run {run + 5}: no such run"):
            store.add_stream_rows(run + 5, "mouse_xy", [0.0], [1], [0], [True])
        assert store.stream_rows(run, "mouse_xy")[0].size == 0
        store.add_stream_rows(run, "mouse_xy", [0.0], [1], [0], [True])  # the connection is usable after
        assert store.stream_rows(run, "mouse_xy")[1].tolist() == [1]


def test_every_committed_batch_survives_a_sigkill(tmp_path):
    """The writer process kills itself with frames appended but not flushed: exactly the committed rows remain."""
    path = tmp_path / "s.db"
    script = textwrap.dedent(f"""
        import os, signal, sys
        import numpy as np
        from bench.sensors.input_event import MotionFrames
        from bench.store import Store
        from bench.store.streams import StreamWriter
        store = Store({str(path)!r})
        run = store.start_run(protocol_name="stream", protocol_version="1", robot="pkm5", config={{}})
        writer = StreamWriter(store, run, "mouse_xy", batch_s=1e9, batch_rows=500)
        for start in range(0, 5200, 100):
            k = np.arange(start, start + 100)
            writer.append(MotionFrames(k * 1e-4, np.ones(100, np.int64), np.zeros(100, np.int64), np.ones(100, bool)))
        print(run, writer.committed, flush=True)
        os.kill(os.getpid(), signal.SIGKILL)
    """)
    env = {**os.environ, "PYTHONPATH": os.getcwd() + os.pathsep + os.environ.get("PYTHONPATH", "")}
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=120)
    assert result.returncode == -9
    run, committed = map(int, result.stdout.split())
    assert committed == 5000  # 200 rows were waiting for the next batch
    with Store(path, read_only=True) as store:
        t, dx, _, _ = store.stream_rows(run, "mouse_xy")
    assert len(t) == committed and np.array_equal(t, np.arange(committed) * 1e-4)
    with sqlite3.connect(path) as db:
        assert db.execute("PRAGMA integrity_check").fetchone() == ("ok",)
