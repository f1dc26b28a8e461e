"""The lab store carries each run's and calibration's local checksum (lab schema 5): ``bench store check
postgresql://...`` names a record changed on the server, and the lab's readers (export, report, ``bench runs``)
refuse it in one line; an interrupted run (stored ``running``) and a resumed run synced again check ok; records
synced before schema 5 are named as not checked. Real PostgreSQL (``postgres_support``)."""

from __future__ import annotations

import sqlite3

import pytest

psycopg = pytest.importorskip("psycopg", reason='the lab store needs psycopg 3 (pip install "psycopg[binary]")')

from postgres_support import lab_server, lab_url, make_store  # noqa: E402, F401  (fixtures)

from bench.cli import main  # noqa: E402
from bench.store import Store  # noqa: E402
from bench.store.lab import LAB_SCHEMA_VERSION, LabStore, sync_store  # noqa: E402
from bench.store.record_checksum import seal_run  # noqa: E402

_SETTINGS = '{"registrations": [{"segment": 1, "u_mm": 0.731, "utc": "2026-12-02T09:00:00+00:00"}]}'
_CHANGED = "its stored bytes no longer match their checksum (changed since it was stored)"


def _store(tmp_path, bench="bench-a", samples=(6, 4), name="a.db"):
    """A store of completed runs; run 1 holds a registration in its settings, run 2 (when there is one) is left
    ``running`` by a process that is gone (it reads as interrupted); both sealed as bench seals its own."""
    path = make_store(tmp_path / name, bench, list(samples))
    db = sqlite3.connect(path)
    with db:
        db.execute("UPDATE runs SET settings_json = ? WHERE id = 1", (_SETTINGS,))
        seal_run(db, 1)
        if len(samples) > 1:
            db.execute("UPDATE runs SET status = 'running', ended_utc = NULL WHERE id = 2")
            seal_run(db, 2)
    db.close()
    return path


def _synced(tmp_path, url, **kwargs):
    with Store(_store(tmp_path, **kwargs), bench=kwargs.get("bench", "bench-a")) as store:
        sync_store(store, url)
        return store.runs(), store.calibrations()


def _check(url: str, capsys) -> tuple[int, list[str], list[str]]:
    capsys.readouterr()
    code = main(["store", "check", url])
    out, err = capsys.readouterr()
    return code, out.splitlines(), err.splitlines()


def test_the_lab_holds_each_records_local_checksum_and_an_interrupted_run_checks_ok(tmp_path, lab_url, capsys):
    path = _store(tmp_path)
    with Store(path) as store:
        sync_store(store, lab_url)
        local = store.runs()
    assert [(r.status, r.reason) for r in local] == [
        ("completed", None),
        ("interrupted", "no process owns it; next: bench resume 2"),
    ]
    db = sqlite3.connect(path)
    sealed = db.execute("SELECT uuid, checksum FROM runs UNION ALL SELECT uuid, checksum FROM calibrations")
    sealed = dict(sealed.fetchall())
    db.close()
    with LabStore(lab_url) as lab:
        held = lab.query(
            "SELECT uuid::text, checksum FROM bench.runs UNION ALL SELECT uuid::text, checksum FROM bench.calibrations"
        )
        stored_status = lab.query("SELECT status, read_status FROM bench.runs WHERE local_id = 2")
        assert lab.runs() == local  # the lab shows each run as its bench reads it
    assert dict(held) == sealed and len(sealed) == 3 and all(len(c) == 64 for c in sealed.values())
    assert stored_status == [("running", "interrupted")]  # the stored status, which the checksum covers
    shown = lab_url.replace("bench-test-pw", "***")
    assert _check(lab_url, capsys) == (0, [f"{shown}: ok"], [])
    assert main(["runs", "--store", lab_url]) == 0
    assert "interrupted" in capsys.readouterr().out


def test_a_changed_digit_in_settings_or_calibration_params_is_named_and_refused(tmp_path, lab_url, capsys):
    runs, (calibration,) = _synced(tmp_path, lab_url)
    out = tmp_path / "run.csv"
    assert main(["export", "bench-a/1", "--store", lab_url, "--out", str(out)]) == 0
    with psycopg.connect(lab_url, autocommit=True) as conn:
        conn.execute(
            "UPDATE bench.runs SET settings_json = replace(settings_json, '0.731', '0.781') WHERE local_id = 1"
        )
        conn.execute("UPDATE bench.calibrations SET params_json = replace(params_json, '0.03175', '0.03195')")
    shown = lab_url.replace("bench-test-pw", "***")
    code, lines, err = _check(lab_url, capsys)
    assert code == 1
    assert sorted(lines) == sorted(
        [
            f"{shown}: run bench-a/1 ({runs[0].uuid[:8]}): {_CHANGED}",
            f"{shown}: calibration bench-a/1 ({calibration.uuid[:8]}): {_CHANGED}",
        ]
    )
    assert err[-1] == f"bench: 2 problem(s) in {shown}; work on a backup copy"
    for command in (["export", "bench-a/1", "--out", str(tmp_path / "again.csv")], ["report", "bench-a/1"]):
        capsys.readouterr()
        assert main([*command, "--store", lab_url]) == 1
        assert capsys.readouterr().err == (
            f"bench: error: store {shown}: run bench-a/1 is damaged: {_CHANGED}; it is refused, nothing computed from "
            f"it: list the damage with `bench store check {shown}` and read a backup copy\n"
        )
    assert not (tmp_path / "again.csv").exists()
    # the other run is read as before: a run damaged on the server does not stop reading the rest of the lab
    assert main(["export", runs[1].uuid, "--store", lab_url, "--out", str(tmp_path / "other.csv")]) == 0
    assert (tmp_path / "other.csv").read_text() != ""
    with psycopg.connect(lab_url, autocommit=True) as conn:  # the run mended: its report reads the calibration, refused
        conn.execute(
            "UPDATE bench.runs SET settings_json = replace(settings_json, '0.781', '0.731') WHERE local_id = 1"
        )
    capsys.readouterr()
    assert main(["report", "bench-a/1", "--store", lab_url]) == 1
    assert capsys.readouterr().err.startswith(
        f"bench: error: store {shown}: calibration bench-a/1 is damaged: {_CHANGED}"
    )


def test_a_shown_status_that_does_not_follow_from_the_stored_one_is_named(tmp_path, lab_url, capsys):
    runs, _ = _synced(tmp_path, lab_url)
    with psycopg.connect(lab_url, autocommit=True) as conn:  # the interrupted run shown as completed
        conn.execute("UPDATE bench.runs SET read_status = 'completed', read_reason = NULL WHERE local_id = 2")
    shown = lab_url.replace("bench-test-pw", "***")
    code, lines, _ = _check(lab_url, capsys)
    assert (code, lines) == (
        1,
        [
            f"{shown}: run bench-a/2 ({runs[1].uuid[:8]}): its shown status 'completed' (reason None) does not follow "
            "from its stored status 'running' (reason None)"
        ],
    )
    capsys.readouterr()
    assert main(["runs", "--store", lab_url]) == 1
    assert capsys.readouterr().err.startswith(f"bench: error: store {shown}: run bench-a/2 is damaged: its shown")


def test_a_run_linked_to_another_calibration_on_the_server_is_named_and_refused(tmp_path, lab_url, capsys):
    runs, _ = _synced(tmp_path, lab_url)
    with Store(tmp_path / "a.db", bench="bench-a") as store:  # a second calibration version, synced: not the runs'
        other = store.add_calibration("mouse", {"mm_per_count": 0.0318})
        sync_store(store, lab_url)
    with psycopg.connect(lab_url, autocommit=True) as conn:  # run 1's link (not in its checksum) to the other one
        conn.execute("UPDATE bench.runs SET calibration_uuids_json = %s WHERE local_id = 1", (f'["{other.uuid}"]',))
    shown = lab_url.replace("bench-test-pw", "***")
    problem = "its calibration_uuids_json names calibrations [2] where its checked calibration_ids_json holds [1]"
    code, lines, _ = _check(lab_url, capsys)
    assert (code, lines) == (1, [f"{shown}: run bench-a/1 ({runs[0].uuid[:8]}): {problem}"])
    capsys.readouterr()
    assert main(["report", "bench-a/1", "--store", lab_url]) == 1
    assert capsys.readouterr().err.startswith(f"bench: error: store {shown}: run bench-a/1 is damaged: {problem};")


def test_records_synced_before_schema_5_are_named_not_checked_until_their_bench_syncs_again(tmp_path, lab_url, capsys):
    path = _store(tmp_path, samples=(5,))
    with Store(path, bench="bench-a") as store:
        sync_store(store, lab_url)
        (run,) = store.runs()
        (calibration,) = store.calibrations()
    with psycopg.connect(lab_url, autocommit=True) as conn:  # as schema 4 left it
        for table, column in (
            ("runs", "checksum"),
            ("runs", "read_status"),
            ("runs", "read_reason"),
            ("calibrations", "checksum"),
            ("calibrations", "source_run_local_id"),
        ):
            conn.execute(f"ALTER TABLE bench.{table} DROP COLUMN {column}")
        conn.execute("UPDATE bench.schema_version SET version = 4")
    with Store(_store(tmp_path, "bench-b", samples=(3,), name="b.db"), bench="bench-b") as other:
        assert sync_store(other, lab_url).samples_sent == 3
    shown = lab_url.replace("bench-test-pw", "***")
    with LabStore(lab_url) as lab:
        assert lab.query("SELECT version FROM bench.schema_version") == [(LAB_SCHEMA_VERSION,)]
        assert lab.query("SELECT bench, checksum IS NULL FROM bench.runs ORDER BY bench") == [
            ("bench-a", True),
            ("bench-b", False),
        ]
        assert [r.uuid for r in lab.runs(bench="bench-a")] == [run.uuid]  # read as before, not refused
    not_checked = "synced before lab schema 5, its record carries no checksum (not checked; sync its bench again)"
    assert _check(lab_url, capsys) == (
        0,
        [f"{shown}: ok"],
        [
            f"{shown}: run bench-a/1 ({run.uuid[:8]}): {not_checked}",
            f"{shown}: calibration bench-a/1 ({calibration.uuid[:8]}): {not_checked}",
        ],
    )
    with Store(path, bench="bench-a") as store:
        sync_store(store, lab_url)
    assert _check(lab_url, capsys) == (0, [f"{shown}: ok"], [])


def test_calibrations_carry_their_runs_bench_not_the_name_of_whoever_syncs(tmp_path, lab_url):
    """A file of bench-07's runs synced from another machine (opened as ``lab-desk``): a calibration fitted from a
    run carries that run's bench, one without a source run the file's bench (its runs agree on one)."""
    path = make_store(tmp_path / "b07.db", "bench-07", [4, 4])
    with Store(path, bench="bench-07") as store:
        fitted = store.add_calibration("mouse", {"mm_per_count": 0.0318}, source_run_id=2)
    db = sqlite3.connect(path)
    with db:  # run 2 measured on another bench that wrote into this file (a file carried between benches)
        db.execute("UPDATE runs SET bench = 'bench-09' WHERE id = 2")
        seal_run(db, 2)
    db.close()
    with Store(path, bench="lab-desk") as store:
        sync_store(store, lab_url)
        nominal = store.calibration("mouse", 1)
    with psycopg.connect(lab_url, autocommit=True) as conn:
        labels = dict(conn.execute("SELECT uuid::text, bench FROM bench.calibrations").fetchall())
    # the runs disagree (bench-07, bench-09): the file's bench is the name it was opened with, for want of another
    assert labels == {fitted.uuid: "bench-09", nominal.uuid: "lab-desk"}


def test_a_file_of_one_bench_labels_its_calibrations_with_that_bench(tmp_path, lab_url):
    path = make_store(tmp_path / "b07.db", "bench-07", [4])
    with Store(path, bench="lab-desk") as store:
        sync_store(store, lab_url)
        (calibration,) = store.calibrations()
    with psycopg.connect(lab_url, autocommit=True) as conn:
        held = conn.execute("SELECT bench FROM bench.calibrations WHERE uuid = %s", (calibration.uuid,)).fetchall()
    assert held == [("bench-07",)]


def test_the_lab_summary_refuses_a_run_changed_on_the_server_and_names_it(tmp_path, lab_url, capsys):
    """A run's robot changed on the server (the summary groups by it): the summary is refused in one line naming
    the run, not printed under the other robot; leaving that bench out gives the rest."""
    _synced(tmp_path, lab_url, bench="bench-a", samples=(6,), name="a.db")
    with Store(_store(tmp_path, bench="bench-b", samples=(6,), name="b.db"), bench="bench-b") as store:
        sync_store(store, lab_url)
    summary = ["lab", "summary", "--store", lab_url]
    capsys.readouterr()
    assert main(summary) == 0
    assert "bench-a" in capsys.readouterr().out
    with psycopg.connect(lab_url, autocommit=True) as conn:
        conn.execute("UPDATE bench.runs SET robot = 'delta4' WHERE bench = 'bench-a'")
    assert main(summary) == 1
    out, err = capsys.readouterr()
    assert out == "" and len(err.strip().splitlines()) == 1, err
    assert "bench-a/1" in err and _CHANGED in err
    assert main([*summary, "--bench", "bench-b"]) == 0
    assert "bench-b" in capsys.readouterr().out
