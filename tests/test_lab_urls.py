"""Lab store addresses: every problem is one line, exit 2, with no password shown, before anything connects or a
store file is created; a store path that names nothing is refused, never created, by sync and the readers."""

from __future__ import annotations

import string
from pathlib import Path

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

pytest.importorskip("psycopg", reason='the lab store needs psycopg 3 (pip install "psycopg[binary]")')

from cli_lines import one_error_line as _one_line  # noqa: E402

from bench.cli import main
from bench.store import Store
from bench.store.lab import redacted

SECRET = "s3cr3t-Pw"

BAD_URLS = {  # the URL -> words its one line must hold
    f"postgresql://bench:{SECRET}@[::1/lab": "not a valid PostgreSQL URL",
    f"mysql://bench:{SECRET}@localhost/lab": "expected a postgresql://USER:PASSWORD@HOST/DBNAME URL",
    f"postgresql://bench:{SECRET}@localhost:1/lab?sslmode=bogus": "sslmode 'bogus', expected one of disable, allow,",
    f"postgresql://bench:{SECRET}@localhost:99999/lab": "port '99999', expected a number from 1 to 65535",
    f"postgresql://bench:{SECRET}@localhost/lab?colour=blue": '"colour"',
    f"postgresql://bench@localhost/lab?password={SECRET}&sslmode=sometimes": "sslmode 'sometimes', expected one of",
    # checked before connecting (libpq names these after the host it tried, psycopg reads connect_timeout itself)
    f"postgresql://bench:{SECRET}@localhost:1/lab?keepalives=x": "keepalives 'x', expected an integer",
    f"postgresql://bench:{SECRET}@localhost:1/lab?connect_timeout=abc": "connect_timeout 'abc', expected an integer",
}


@pytest.mark.parametrize("url", sorted(BAD_URLS))
@pytest.mark.parametrize(
    "command",
    [
        ["sync", "--store", "STORE", "--to", "URL"],
        ["runs", "--store", "URL"],
        ["export", "1", "--store", "URL"],
        ["lab", "summary", "--store", "URL"],
        ["report", "1", "--store", "URL"],
        ["store", "check", "URL"],
    ],
)
def test_every_bad_url_is_one_line_exit_2_and_no_password(tmp_path, capsys, url, command):
    store = tmp_path / "bench.db"
    Store(store).close()
    before = store.read_bytes()
    argv = [{"URL": url, "STORE": str(store)}.get(word, word) for word in command]
    assert main(argv) == 2
    line = _one_line(capsys)
    assert line.startswith("bench: error: ") and BAD_URLS[url] in line
    assert SECRET not in line
    assert store.read_bytes() == before


@pytest.mark.parametrize(
    "command", [["sync", "--to", "postgresql://bench@localhost/lab"], ["runs"], ["export", "1"], ["report", "1"]]
)
def test_a_store_path_that_names_nothing_is_refused_never_created(tmp_path, capsys, command):
    typo = tmp_path / "typo.db"
    assert main([*command, "--store", str(typo)]) == 2
    assert f"--store {typo}: no " in _one_line(capsys)
    assert not typo.exists() and not list(tmp_path.iterdir())


@pytest.mark.parametrize(
    "command",
    [
        ["sync", "--to", "postgresql://bench@localhost:1/other"],
        ["backup", "copy.db"],
        ["resume", "1"],
        ["calibrate", "1"],
        ["analyze", "path-run", "1"],
        ["run", "examples/iso9283_pose_quick.toml", "--sim"],
    ],
)
def test_a_lab_address_where_only_a_store_file_will_do_is_one_line_without_its_password(
    tmp_path, capsys, monkeypatch, command
):
    monkeypatch.chdir(tmp_path)
    url = f"postgresql://bench:{SECRET}@localhost:1/lab"
    examples = Path(__file__).resolve().parents[1] / "examples"
    argv = [
        str(examples / word.removeprefix("examples/")) if word.startswith("examples/") else word for word in command
    ]
    assert main([*argv, "--store", url]) == 2
    line = _one_line(capsys)  # was "folder postgresql:/bench:PASSWORD@localhost:1 does not exist"
    assert line.endswith("a URL, expected a run store file (bench.db) here") and SECRET not in line
    assert not list(tmp_path.iterdir())


_PASSWORD_CHARS = string.ascii_letters + string.digits + "!$%&()*+,-.:;=@[]^_{|}~/"


@settings(max_examples=300, deadline=None)
@given(
    user=st.text(string.ascii_letters + string.digits + "_.-", max_size=12),
    password=st.text(_PASSWORD_CHARS, min_size=4, max_size=24).filter(lambda p: not p.startswith("@")),
    host=st.sampled_from(["localhost", "[::1]", "[::1", "db.lab:5432", "", "10.0.0.7:x"]),
    rest=st.sampled_from(["/lab", "/lab?sslmode=require", "/", "", "/lab?host=/tmp&options=a@b"]),
    scheme=st.sampled_from(["postgresql", "postgres", "mysql", "http"]),
)
def test_redacted_never_shows_the_password_and_never_fails(user, password, host, rest, scheme):
    assume(password not in f"{scheme}://{user}:***@{host}{rest}")
    shown = redacted(f"{scheme}://{user}:{password}@{host}{rest}")
    assert password not in shown
    assert shown.startswith(f"{scheme}://{user}:***@")
    in_query = password.replace("&", "")
    assume(len(in_query) >= 4 and in_query not in f"postgresql://{host}{rest}?password=***&sslmode=require")
    assert in_query not in redacted(f"postgresql://{host}{rest}?password={in_query}&sslmode=require")
