"""How many connections a sync holds: each bench at most ``LANES`` at once (its first connection is also the first
sender), counted by the server itself from its log of every session (``postgres_support.connection_peaks``), so a
crowd of benches needs a known number of the server's ``max_connections`` (benchmarks/drill_lab_crowd.py)."""

from __future__ import annotations

import threading

import pytest

psycopg = pytest.importorskip("psycopg", reason='the lab store needs psycopg 3 (pip install "psycopg[binary]")')

from postgres_support import Cluster, connection_peaks, lab_server, lab_url, log_sessions, make_store  # noqa: E402, F401

from bench.store import Store  # noqa: E402
from bench.store.lab import sync_store  # noqa: E402
from bench.store.lab_sync import LANES  # noqa: E402

BENCHES = 3


def test_each_bench_holds_at_most_its_lanes_and_uses_them(tmp_path, lab_server, lab_url):
    if not isinstance(lab_server, Cluster):
        pytest.skip("counting sessions reads the server's log: only on the tests' own cluster")
    dbname = lab_url.split("?")[0].rsplit("/", 1)[1]
    log_sessions(lab_server)
    paths = [make_store(tmp_path / f"b{i}.db", f"bench-{i}", [120, 80, 50]) for i in range(BENCHES)]
    with Store(paths[0], read_only=True) as store:
        sync_store(store, f"{lab_url}&application_name=schema-maker", batch_size=1000)  # the schema, first
    go, failures = threading.Barrier(BENCHES - 1), []

    def bench(i: int) -> None:
        with Store(paths[i], read_only=True) as store:
            go.wait()
            try:
                result = sync_store(store, f"{lab_url}&application_name=bench-{i}", batch_size=30)
                assert result.samples_sent == 250
            except Exception as exc:  # noqa: BLE001 - reported by the test below
                failures.append(exc)

    threads = [threading.Thread(target=bench, args=(i,)) for i in range(1, BENCHES)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert not failures
    peaks, _ = connection_peaks(lab_server, dbname)
    # a free server: every bench opens all its lanes (the bound is reached, so a count that saw nothing would fail)
    assert {name: peaks[name] for name in peaks if name.startswith("bench-")} == {
        f"bench-{i}": LANES for i in range(1, BENCHES)
    }
    assert peaks["schema-maker"] == LANES
