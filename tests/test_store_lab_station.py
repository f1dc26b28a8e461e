"""``[lab_store]`` in the station file: every run is synced when it ends; a failed sync (server down) is one line on
stderr, the local run is kept and completed, and the next ``bench sync`` catches up. Real PostgreSQL server."""

from __future__ import annotations

from pathlib import Path

import pytest

psycopg = pytest.importorskip("psycopg", reason='the lab store needs psycopg 3 (pip install "psycopg[binary]")')

from postgres_support import lab_server, lab_url  # noqa: E402, F401  (fixtures)

from bench.cli import main  # noqa: E402
from bench.errors import ConfigError  # noqa: E402
from bench.rigs.station import LabStoreSpec, load_station  # noqa: E402
from bench.store import Store  # noqa: E402
from bench.store.lab import LabStore, rows_checksum  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
QUICK = ROOT / "examples" / "iso9283_pose_quick.toml"
STATION = ROOT / "examples" / "stations" / "pkm5_mice.toml"
UNREACHABLE = "postgresql://bench:pw@127.0.0.1:9/lab?connect_timeout=2"


def station_with(tmp_path: Path, lab_store: str) -> Path:
    path = tmp_path / "station.toml"
    path.write_text(STATION.read_text() + "\n[lab_store]\n" + lab_store)
    return path


def run_quick(station: Path, store: Path) -> int:
    return main(
        [
            "run",
            str(QUICK),
            "--station",
            str(station),
            "--sim",
            "--store",
            str(store),
            "--no-progress",
            "--speed-factor",
            "300",
        ]
    )


def test_lab_store_table_is_read_and_checked(tmp_path):
    assert load_station(station_with(tmp_path, f'url = "{UNREACHABLE}"\n')).lab_store == LabStoreSpec(UNREACHABLE)
    spec = load_station(station_with(tmp_path, 'url = "postgres://lab/x"\nauto_sync = false\n')).lab_store
    assert spec == LabStoreSpec("postgres://lab/x", auto_sync=False)
    with pytest.raises(ConfigError, match=r"lab_store.url = mysql://lab/x: expected a postgresql://USER:PASSWORD@"):
        load_station(station_with(tmp_path, 'url = "mysql://lab/x"\n'))
    with pytest.raises(
        ConfigError,
        match=r"lab_store.url = postgresql://b:\*\*\*@\[::1/lab: not a valid PostgreSQL"
        r" URL \(.*\)$",
    ) as refused:
        load_station(station_with(tmp_path, 'url = "postgresql://b:s3cret@[::1/lab"\n'))
    assert "s3cret" not in str(refused.value)
    with pytest.raises(ConfigError, match=r"unknown key 'lab_store.sync', expected one of auto_sync, url"):
        load_station(station_with(tmp_path, 'url = "postgres://lab/x"\nsync = true\n'))
    assert "127.0.0.1:9" not in str(load_station(station_with(tmp_path, f'url = "{UNREACHABLE}"\n')).settings())


def test_each_run_is_synced_when_it_ends(tmp_path, lab_url, capsys):
    store = tmp_path / "b.db"
    assert run_quick(station_with(tmp_path, f'url = "{lab_url}"\n'), store) == 0
    err = capsys.readouterr().err
    assert "bench: synced to the lab store postgresql://bench:***@" in err and ": 15 new samples" in err
    with Store(store) as local, LabStore(lab_url) as lab:
        (run,) = local.runs()
        (synced,) = lab.runs()
        assert (synced.uuid, synced.status, synced.n_samples) == (run.uuid, "completed", 15)
        assert lab.checksum(run.uuid) == rows_checksum(local.stored_rows(run.id))


def test_a_sync_that_fails_keeps_the_run_and_the_next_sync_catches_up(tmp_path, lab_url, capsys):
    store = tmp_path / "b.db"
    assert run_quick(station_with(tmp_path, f'url = "{UNREACHABLE}"\n'), store) == 0
    err = [line for line in capsys.readouterr().err.splitlines() if "lab store" in line]
    assert len(err) == 1 and err[0].startswith(
        "bench: lab store sync failed, the run is kept locally (bench sync catches up): lab store "
        "postgresql://bench:***@127.0.0.1:9/lab?connect_timeout=2: server unreachable ("
    )
    with Store(store) as local:
        (run,) = local.runs()
        assert (run.status, run.n_samples) == ("completed", 15)
    assert main(["sync", "--store", str(store), "--to", lab_url]) == 0
    with LabStore(lab_url) as lab:
        assert [(r.uuid, r.status, r.n_samples) for r in lab.runs()] == [(run.uuid, "completed", 15)]


def test_auto_sync_false_leaves_the_server_alone(tmp_path, lab_url, capsys):
    assert run_quick(station_with(tmp_path, f'url = "{lab_url}"\nauto_sync = false\n'), tmp_path / "b.db") == 0
    assert "lab store" not in capsys.readouterr().err
    with psycopg.connect(lab_url) as conn:
        assert conn.execute("SELECT to_regclass('bench.runs')").fetchone() == (None,)
