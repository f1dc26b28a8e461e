"""Store robustness: every database error one line naming the file and what to do; another application's SQLite
file refused untouched; readers never create a store; ``bench store check`` one line per problem."""

from __future__ import annotations

import argparse
import sqlite3
from pathlib import Path

import pytest
from cli_lines import one_error_line as _one_error_line

from bench.cli import build_parser, main
from bench.store import Store
from bench.store.connection import StoreError, check_store

ROOT = Path(__file__).resolve().parents[1]
QUICK = ROOT / "examples" / "iso9283_pose_quick.toml"


@pytest.fixture()
def sound_store(tmp_path) -> Path:
    path = tmp_path / "bench.db"
    with Store(path) as store:
        run_id = store.start_run(protocol_name="p", protocol_version="1", robot="pkm5", config={})
        for step in range(300):
            store.add_sample(run_id, step, values={"x_mm": step * 0.5}, t_s=float(step))
        store.set_status(run_id, "completed")
    return path


def _damaged(sound: Path) -> Path:
    """The sound store with pages 3 to 5 overwritten (the sample table's b-tree pages)."""
    data = bytearray(sound.read_bytes())
    page = 4096
    assert len(data) >= 6 * page
    data[3 * page : 6 * page] = b"\x5a" * (3 * page)
    damaged = sound.with_name("damaged.db")
    damaged.write_bytes(bytes(data))
    return damaged


def test_another_applications_sqlite_file_is_refused_and_untouched(tmp_path, capsys):
    other = tmp_path / "notes.db"
    with sqlite3.connect(other) as db:
        db.execute("CREATE TABLE notes (id INTEGER PRIMARY KEY, text TEXT)")
        db.execute("INSERT INTO notes (text) VALUES ('keep me')")
    db.close()
    before = other.read_bytes()
    expected = (
        f"bench: error: --store {other}: not a bench store (its tables are notes; no runs table); left "
        "untouched, expected a bench.db that bench wrote or a new file name"
    )
    for command in (["runs"], ["run", str(QUICK), "--sim", "--no-progress"], ["export", "1"], ["report", "1"]):
        assert main([*command, "--store", str(other)]) == 2
        assert _one_error_line(capsys) == expected
    assert other.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.db"]  # no journal, no lock, no table added


def test_readers_never_create_a_store(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no demo-out/ here (a checkout that ran ./dev demo has one): the message has no hint
    missing = tmp_path / "typo.db"
    refused = f"bench: error: --store {missing}: no run store there, expected the bench.db a run wrote (--store)"
    for command in (
        ["runs"],
        ["export", "1"],
        ["report", "1"],
        ["report", "1", "--compare", "2"],
        ["backup", str(tmp_path / "copy.db")],
        ["analyze", "path-run", "1"],
        ["analyze", "positioning-run", "1"],
        ["analyze", "iso230-2-run", "1"],
        ["sync", "--to", "postgresql://bench@/lab?host=/nowhere"],  # (refused before connecting)
    ):
        assert main([*command, "--store", str(missing)]) == 2
        assert _one_error_line(capsys) == refused, command
    assert main(["store", "check", str(missing)]) == 2
    assert _one_error_line(capsys) == refused.replace("--store", "STORE", 1)
    with pytest.raises(Exception, match=f"--store {missing}: no run store there"):
        Store(missing, read_only=True)
    assert list(tmp_path.iterdir()) == []


def _commands_with_a_store(parser: argparse.ArgumentParser, words: tuple[str, ...] = ()):
    """``(words, parser)`` of every sub-command whose parser has a ``--store`` option, found by walking the CLI."""
    parser.fill()  # the deferred arguments too (bench/commands/lazy.py)
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _commands_with_a_store(sub, (*words, name))
        elif "--store" in action.option_strings:
            yield words, parser


def test_every_command_that_reads_runs_refuses_a_missing_store(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no demo-out/ here: the message has no hint
    missing = tmp_path / "typo.db"
    walked = []
    for words, parser in _commands_with_a_store(build_parser()):
        if parser.get_default("creates_store"):  # bench run and bench gui start runs: a new store is theirs to make
            continue
        if parser.get_default("lab_store_only"):  # bench lab summary reads a lab store: a file is the wrong kind
            assert main([*words, "--store", str(missing)]) == 2
            assert _one_error_line(capsys).endswith("expected a postgresql://USER:PASSWORD@HOST/DBNAME URL")
            continue
        positionals = [a for a in parser._actions if not a.option_strings and a.required]
        argv = [*words, *(str(tmp_path / "out.db") if a.dest == "destination" else "1" for a in positionals)]
        argv += ["--to", "postgresql://u@localhost:1/lab"] if words == ("sync",) else []
        assert main([*argv, "--store", str(missing)]) == 2, argv
        assert _one_error_line(capsys) == (
            f"bench: error: --store {missing}: no run store there, expected the bench.db a run wrote (--store)"
        ), argv
        walked.append(" ".join(words))
    assert sorted(p.name for p in tmp_path.iterdir()) == []
    # the walk found the readers (a command added with a --store is walked too; these must be among them)
    assert {"calibrate", "resume", "report", "runs", "export", "backup", "sync", "analyze path-run"} <= set(walked)
    assert main(["store", "check", str(missing)]) == 2
    assert f"STORE {missing}: no run store there" in _one_error_line(capsys)  # the positional, named as --help names it
    assert not missing.exists()


def test_store_check_of_a_file_that_is_no_database_reports_it_as_its_one_problem(tmp_path, capsys):
    text = tmp_path / "notes.txt"
    text.write_text("not a store\n")
    assert main(["store", "check", str(text)]) == 1  # was "database: ...; check the store with `bench store check`"
    captured = capsys.readouterr()
    assert captured.out == f"{text}: not a usable bench store (file is not a database)\n"
    assert captured.err == f"bench: 1 problem(s) in {text}; work on a backup copy\n"


def test_a_damaged_store_is_one_line_naming_the_file_and_what_to_do(sound_store, capsys):
    damaged = _damaged(sound_store)
    advice = f"the file is damaged: check it with `bench store check {damaged}` and work on a backup copy"
    assert main(["export", "1", "--store", str(damaged), "--out", str(damaged.with_suffix(".csv"))]) == 1
    assert _one_error_line(capsys) == f"bench: error: store {damaged}: database disk image is malformed; {advice}"
    with Store(damaged, read_only=True) as store, pytest.raises(StoreError, match="disk image is malformed"):
        store.samples(1)
    assert main(["store", "check", str(damaged)]) == 1
    captured = capsys.readouterr()
    assert captured.out.splitlines() == [f"{damaged}: database disk image is malformed"]
    assert captured.err == f"bench: 1 problem(s) in {damaged}; work on a backup copy\n"


def test_store_check_says_ok_and_names_each_orphan_row(sound_store, capsys):
    assert main(["store", "check", str(sound_store)]) == 0
    assert capsys.readouterr().out == f"{sound_store}: ok\n"
    with sqlite3.connect(sound_store) as db:  # foreign keys are off in a plain connection: orphans get in
        db.execute(
            "INSERT INTO samples (run_id, step_index, kind, t_s, wall_utc, values_json)"
            " VALUES (7, 0, 'pose', 0, '2026-12-01', '{}')"
        )
        (rowid,) = db.execute("SELECT id FROM samples WHERE run_id = 7").fetchone()
    db.close()
    assert check_store(str(sound_store)) == [
        f"{sound_store}: table samples row {rowid}: runs id missing (foreign key 0)",
        f"{sound_store}: run 7 sample at step 0 (samples row {rowid}): it has no checksum (written outside bench)",
    ]


def test_a_read_only_store_reads_and_a_write_is_one_line(sound_store):
    with Store(sound_store, read_only=True) as store:
        assert [(r.status, r.n_samples) for r in store.runs()] == [("completed", 300)]
        assert store.samples(1)[299].values == {"x_mm": 149.5}
        with pytest.raises(
            StoreError,
            match=f"store {sound_store}: attempt to write a readonly database; the file or its folder is read-only",
        ):
            store.set_status(1, "failed", "x")
