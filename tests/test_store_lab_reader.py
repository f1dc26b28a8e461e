"""Lab-wide use on a real PostgreSQL server: ``bench runs``, ``bench export`` and ``bench report`` (``--compare``,
``--trend``) read a synced run from the lab store exactly as from its bench's file; runs are named by BENCH/ID, by
UUID (prefix) or by a bare id when only one bench has it; bad input is one line."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest

pytest.importorskip("psycopg", reason='the lab store needs psycopg 3 (pip install "psycopg[binary]")')
matplotlib = pytest.importorskip("matplotlib")

from cli_lines import one_error_line as _one_error_line  # noqa: E402
from postgres_support import PASSWORD, lab_server, lab_url  # noqa: E402, F401  (fixtures)

from bench.cli import main  # noqa: E402
from bench.store import Store  # noqa: E402

DATA = Path(__file__).parent / "data"
V0 = DATA / "store_schema0.db"  # a pose run (1, 15 samples) and a mouse calibration run (2, 100 samples)


@pytest.fixture()
def benches(tmp_path, lab_url, capsys):
    """Two benches, each a migrated copy of the schema-0 fixture (same ids, different UUIDs), synced."""
    paths = {}
    for bench in ("bench-a", "bench-b"):
        paths[bench] = tmp_path / f"{bench}.db"
        shutil.copy(V0, paths[bench])
        Store(paths[bench], bench=bench).close()
        assert main(["sync", "--store", str(paths[bench]), "--to", lab_url]) == 0
    capsys.readouterr()
    return paths


def _stdout_lines(capsys) -> list[str]:
    return capsys.readouterr().out.splitlines()


def _without_generation_time(html: str) -> str:
    return re.sub(r"<td>Generated \(UTC\)</td><td>[^<]*</td>", "", html)


def test_runs_filters_alike_on_file_and_server(benches, lab_url, capsys):
    filters = ["--bench", "bench-a", "--robot", "pkm5", "--since", "2026-11-01", "--json"]
    assert main(["runs", "--store", str(benches["bench-a"]), *filters]) == 0
    from_file = [json.loads(line) for line in _stdout_lines(capsys)]
    assert main(["runs", "--store", lab_url, *filters]) == 0
    from_server = [json.loads(line) for line in _stdout_lines(capsys)]
    assert [(r["bench"], r["id"], r["protocol_name"], r["n_samples"]) for r in from_server] == [
        ("bench-a", 1, "iso9283_pose", 15),
        ("bench-a", 2, "mouse_calibration", 100),
    ]
    assert from_server == from_file
    assert main(["runs", "--store", lab_url, "--json", "--since", "2026-12-02"]) == 0
    assert _stdout_lines(capsys) == []  # the fixture's runs started on 2026-12-01


def test_export_from_the_server_equals_the_file(benches, lab_url, tmp_path, capsys):
    with Store(benches["bench-b"], read_only=True) as store:
        uuid = store.run(2).uuid
    for name, run_id, _kind in (("bench-a/1", 1, "pose"), (uuid[:8], 2, "mouse")):
        assert main(["export", name, "--store", lab_url, "--out", str(tmp_path / "server.csv")]) == 0
        assert (
            main(["export", str(run_id), "--store", str(benches["bench-a"]), "--out", str(tmp_path / "file.csv")]) == 0
        )
        server = (tmp_path / "server.csv").read_text()
        assert server == (tmp_path / "file.csv").read_text() == (DATA / f"store_schema0_run{run_id}.csv").read_text()
        meta = json.loads((tmp_path / "server.csv.meta.json").read_text())
        assert (meta["run_id"], meta["bench"]) == (run_id, "bench-a" if name == "bench-a/1" else "bench-b")
    assert _stdout_lines(capsys) == [str(tmp_path / "server.csv"), str(tmp_path / "file.csv")] * 2
    assert main(["export", "bench-a/1", "--store", str(benches["bench-a"]), "--out", str(tmp_path / "n.csv")]) == 0
    assert (tmp_path / "n.csv").read_text() == (DATA / "store_schema0_run1.csv").read_text()  # names on a file too


def test_report_compare_and_trend_from_the_server_equal_the_file(benches, lab_url, tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(matplotlib.rcParams, "svg.hashsalt", "bench-test")  # SVG ids from content, not chance
    common = ["--format", "html", "--quiet"]
    assert main(["report", "bench-a/1", "--store", lab_url, "--out", str(tmp_path / "server"), *common]) == 0
    assert main(["report", "1", "--store", str(benches["bench-a"]), "--out", str(tmp_path / "file"), *common]) == 0
    server, file = ((tmp_path / where / "report_run1.html").read_text() for where in ("server", "file"))
    assert "Generated (UTC)" in server and _without_generation_time(server) == _without_generation_time(file)
    assert (tmp_path / "server" / "run1_samples.csv").read_bytes() == (
        tmp_path / "file" / "run1_samples.csv"
    ).read_bytes()
    capsys.readouterr()
    # across benches: the second run of id 1 is shown as 10001, its raw data beside the first's
    assert (
        main(
            [
                "report",
                "bench-a/1",
                "--compare",
                "bench-b/1",
                "--store",
                lab_url,
                "--out",
                str(tmp_path / "compare"),
                *common,
            ]
        )
        == 0
    )
    assert sorted(p.name for p in (tmp_path / "compare").iterdir()) == [
        "compare_run1_run10001.html",
        "report-numbers.tsv",  # the issue counter of the report numbers (bench.reports.numbering)
        "run10001_samples.csv",
        "run1_samples.csv",
    ]
    assert (tmp_path / "compare" / "run10001_samples.csv").read_bytes() == (
        tmp_path / "file" / "run1_samples.csv"
    ).read_bytes()
    assert (
        main(
            [
                "report",
                "bench-a/1",
                "--trend",
                "bench-b/1",
                "--store",
                lab_url,
                "--out",
                str(tmp_path / "trend"),
                *common,
            ]
        )
        == 0
    )
    assert (tmp_path / "trend" / "trend_run1_run10001.html").is_file()


def test_bad_names_and_servers_are_one_line_each(benches, lab_url, tmp_path, capsys):
    from bench.store.lab import redacted

    shown = redacted(lab_url)
    out = ["--out", str(tmp_path / "r"), "--format", "html", "--quiet"]
    assert main(["report", "1", "--store", lab_url, *out]) == 2
    line = _one_error_line(capsys)
    assert line.startswith(f"bench: error: run 1: names 2 runs in lab store {shown} (bench-a/1 (")
    assert line.endswith("); name one as BENCH/ID or by its UUID") and "bench-b/1 (" in line
    assert main(["export", "bench-a/9", "--store", lab_url]) == 2
    assert _one_error_line(capsys) == f"bench: error: run bench-a/9: no such run in lab store {shown}"
    assert main(["export", "first", "--store", lab_url]) == 2
    assert _one_error_line(capsys) == (
        "bench: error: run 'first': expected a run id, BENCH/ID or a run UUID (or its first 8+ hex digits)"
    )
    assert main(["report", "bench-a/1", "--store", "postgresql://bench@/lab?colour=blue", *out]) == 2
    assert _one_error_line(capsys).startswith(
        "bench: error: --store postgresql://bench@/lab?colour=blue: not a valid PostgreSQL URL (invalid "
    )
    wrong = lab_url.replace(PASSWORD, "not-the-password") if PASSWORD in lab_url else lab_url + "&password=nope"
    assert main(["export", "bench-a/1", "--store", wrong]) == 1
    line = _one_error_line(capsys)
    assert "bad credentials (" in line and "password authentication failed" in line and "not-the-password" not in line
    assert main(["runs", "--store", "postgresql://bench:pw@127.0.0.1:9/lab?connect_timeout=2"]) == 1
    assert _one_error_line(capsys).startswith(
        "bench: error: lab store postgresql://bench:***@127.0.0.1:9/lab?connect_timeout=2: server unreachable ("
    )
    assert not (tmp_path / "r").exists()
