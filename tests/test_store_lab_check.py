"""The lab store carries each sample's checksum (lab schema 4) and ``bench store check postgresql://...`` finds a
changed value on the server: in the stored text, in ``t_s`` by one ulp, or in a typed column. Also schema 4's
per-statement run check, which replaced the per-row foreign key. Real PostgreSQL (``postgres_support``)."""

from __future__ import annotations

import sqlite3

import pytest

psycopg = pytest.importorskip("psycopg", reason='the lab store needs psycopg 3 (pip install "psycopg[binary]")')

from postgres_support import lab_server, lab_url, make_store  # noqa: E402, F401  (fixtures)

from bench.cli import main  # noqa: E402
from bench.store import Store  # noqa: E402
from bench.store.lab import LAB_SCHEMA_VERSION, LabStore, sync_store  # noqa: E402


def _synced(tmp_path, lab_url, samples=(12, 7)):
    path = make_store(tmp_path / "a.db", "bench-a", list(samples))
    with Store(path) as store:
        sync_store(store, lab_url)
        runs = store.runs()
    return path, runs


def _check(url: str, capsys) -> tuple[int, list[str], list[str]]:
    capsys.readouterr()
    code = main(["store", "check", url])
    out, err = capsys.readouterr()
    return code, out.splitlines(), err.splitlines()


def test_the_server_holds_each_samples_checksum_as_the_bench_stored_it(tmp_path, lab_url):
    path, runs = _synced(tmp_path, lab_url)
    db = sqlite3.connect(path)
    local = {
        (uuid, step): checksum
        for uuid, step, checksum in db.execute(
            "SELECT r.uuid, s.step_index, s.checksum FROM samples s JOIN runs r ON r.id = s.run_id"
        )
    }
    db.close()
    with LabStore(lab_url) as lab:
        held = {(u, s): c for u, s, c in lab.query("SELECT run_uuid::text, step_index, checksum FROM bench.samples")}
    assert len(held) == 19 and held == local and all(len(c) == 64 for c in held.values())


def test_store_check_finds_a_changed_digit_a_changed_t_s_and_a_changed_typed_value(tmp_path, lab_url, capsys):
    _, runs = _synced(tmp_path, lab_url)
    shown = lab_url.replace("bench-test-pw", "***")
    assert _check(lab_url, capsys) == (0, [f"{shown}: ok"], [])
    first, second = runs[0].uuid, runs[1].uuid
    with psycopg.connect(lab_url, autocommit=True) as conn:
        conn.execute(  # one digit of the stored JSON, as a flipped bit would change it
            "UPDATE bench.samples SET values_json = replace(values_json, '318.3', '318.7')"
            " WHERE run_uuid = %s AND step_index = 5",
            (first,),
        )
        conn.execute(  # t_s one ulp off: the same text to 15 digits
            "UPDATE bench.samples SET t_s = t_s * (1 + 2.0 ^ -52) WHERE run_uuid = %s AND step_index = 9",
            (first,),
        )
        conn.execute(  # the typed column the lab summary reads, its JSON left as it was
            "UPDATE bench.samples SET x_mm = 110.5 WHERE run_uuid = %s AND step_index = 3", (second,)
        )
    code, out, err = _check(lab_url, capsys)
    changed = "its stored bytes no longer match their checksum (changed since it was stored)"
    assert code == 1
    assert (
        sorted(out)
        == sorted(  # (the server lists runs in UUID order)
            [
                f"{shown}: run bench-a/1 ({first[:8]}) sample at step 5: {changed}",
                f"{shown}: run bench-a/1 ({first[:8]}) sample at step 9: {changed}",
                f"{shown}: run bench-a/2 ({second[:8]}) sample at step 3: its typed column x_mm holds 110.5 where its "
                "values_json holds 110.001",
            ]
        )
    )
    assert err[-1] == f"bench: 3 problem(s) in {shown}; work on a backup copy"


def test_a_run_changed_on_the_server_is_refused_by_export_and_report(tmp_path, lab_url, capsys):
    _, runs = _synced(tmp_path, lab_url)
    out = tmp_path / "run.csv"
    assert main(["export", "bench-a/1", "--store", lab_url, "--out", str(out)]) == 0
    with psycopg.connect(lab_url, autocommit=True) as conn:
        conn.execute(
            "UPDATE bench.samples SET values_json = replace(values_json, '318.3', '318.7')"
            " WHERE run_uuid = %s AND step_index = 5",
            (runs[0].uuid,),
        )
    shown = lab_url.replace("bench-test-pw", "***")
    for command in (["export", "bench-a/1", "--out", str(tmp_path / "again.csv")], ["report", "bench-a/1"]):
        capsys.readouterr()
        assert main([*command, "--store", lab_url]) == 1
        assert capsys.readouterr().err.startswith(
            f"bench: error: store {shown}: run 1 sample at step 5 is damaged: its stored bytes no longer "
            "match their checksum"
        )
    assert not (tmp_path / "again.csv").exists()


def test_samples_synced_before_schema_4_are_named_not_counted_as_damage(tmp_path, lab_url, capsys):
    _, runs = _synced(tmp_path, lab_url)
    with psycopg.connect(lab_url, autocommit=True) as conn:
        conn.execute("UPDATE bench.samples SET checksum = NULL WHERE run_uuid = %s", (runs[1].uuid,))
    code, out, err = _check(lab_url, capsys)
    shown = lab_url.replace("bench-test-pw", "***")
    assert (code, out) == (0, [f"{shown}: ok"])
    assert err == [
        f"{shown}: run bench-a/2 ({runs[1].uuid[:8]}): 7 samples synced before lab schema 4 carry no checksum "
        "(not checked)"
    ]


def test_a_sample_of_an_unknown_run_is_refused_and_a_run_with_samples_is_kept(tmp_path, lab_url):
    _, runs = _synced(tmp_path, lab_url)
    with psycopg.connect(lab_url, autocommit=True) as conn:
        with pytest.raises(psycopg.errors.ForeignKeyViolation, match="samples of run 00000000-"):
            conn.execute(
                "INSERT INTO bench.samples (run_uuid, step_index, kind, t_s, wall_utc, values_json) VALUES"
                " ('00000000-0000-0000-0000-000000000001', 1, 'pose', 0, 'w', '{}')"
            )
        with pytest.raises(psycopg.errors.ForeignKeyViolation, match="has samples in bench.samples"):
            conn.execute("DELETE FROM bench.pose_point_sets")  # (the pose keys also hold the run: free it of them)
            conn.execute("DELETE FROM bench.pose_keys")
            conn.execute("DELETE FROM bench.runs WHERE uuid = %s", (runs[0].uuid,))
        held = conn.execute("SELECT count(*) FROM bench.samples").fetchone()[0]
    assert held == 19


def test_a_version_3_lab_store_is_migrated_to_checksums_without_the_row_foreign_key(tmp_path, lab_url, capsys):
    path, runs = _synced(tmp_path, lab_url, samples=(6,))
    with psycopg.connect(lab_url, autocommit=True) as conn:  # as schema 3 left it
        conn.execute("ALTER TABLE bench.samples DROP COLUMN checksum")
        conn.execute("ALTER TABLE bench.samples ADD FOREIGN KEY (run_uuid) REFERENCES bench.runs (uuid)")
        conn.execute("UPDATE bench.schema_version SET version = 3")
    more = make_store(tmp_path / "b.db", "bench-b", [4])
    with Store(more) as store:
        assert sync_store(store, lab_url).samples_sent == 4
    with LabStore(lab_url) as lab:
        assert lab.query("SELECT version FROM bench.schema_version") == [(LAB_SCHEMA_VERSION,)]
        assert lab.query(
            "SELECT count(*) FROM pg_constraint WHERE contype = 'f' AND conrelid = 'bench.samples'::regclass"
        ) == [(0,)]
        assert lab.query("SELECT count(checksum), count(*) FROM bench.samples") == [(4, 10)]
    code, _, err = _check(lab_url, capsys)
    assert code == 0 and err == [
        f"{lab_url.replace('bench-test-pw', '***')}: run bench-a/1 ({runs[0].uuid[:8]}): 6 samples synced before "
        "lab schema 4 carry no checksum (not checked)"
    ]
