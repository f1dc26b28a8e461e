"""A lab URL's option values are checked before anything runs, against the bundled libpq as the oracle: a station
whose ``lab_store.url`` says ``sslmode=bogus`` is refused by ``bench station check`` (one line naming the field, the
URL with its password hidden and what was expected, exit 2), as ``bench sync --to`` refuses it; whatever URL is
written, the check never fails with a traceback and never shows the password."""

from __future__ import annotations

import json
import string
from pathlib import Path
from urllib.parse import quote

import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st

psycopg = pytest.importorskip("psycopg", reason='the lab store needs psycopg 3 (pip install "psycopg[binary]")')

from bench.cli import main  # noqa: E402
from bench.errors import ConfigError  # noqa: E402
from bench.rigs.station import load_station  # noqa: E402
from bench.store.lab import LabURLError, check_lab_url  # noqa: E402
from bench.store.lab_url_options import CHOICES, INTEGER_OPTIONS  # noqa: E402

SECRET = "s3cr3t-Pw"
STATION = Path(__file__).resolve().parents[1] / "examples" / "stations" / "pkm5_mice.toml"
#: nothing listens on port 1 of the loopback: libpq checks the options, then is refused at once (no wait, no DNS)
REFUSED = "127.0.0.1:1"

BAD_OPTIONS = {  # the URL's query -> what the line must say (each passed `bench station check` before)
    "sslmode=bogus": "sslmode 'bogus', expected one of disable, allow, prefer, require, verify-ca, verify-full",
    "sslmode=REQUIRE": "sslmode 'REQUIRE', expected one of disable,",
    "gssencmode=always": "gssencmode 'always', expected one of disable, prefer, require",
    "channel_binding=yes": "channel_binding 'yes', expected one of disable, prefer, require",
    "target_session_attrs=master": "target_session_attrs 'master', expected one of any, read-write, read-only,",
    "connect_timeout=soon": "connect_timeout 'soon', expected an integer",
    "keepalives_idle=1.5": "keepalives_idle '1.5', expected an integer >= 1",
    "port=0": "port '0', expected a number from 1 to 65535",
    "port=5432,5433": "2 ports for 1 hosts, expected one port or one per host",
    "ssl_min_protocol_version=TLSv1.3&ssl_max_protocol_version=TLSv1.2": "ssl_min_protocol_version above ssl_max",
}


def station_with(tmp_path: Path, url: str) -> Path:
    path = tmp_path / "station.toml"
    path.write_text(STATION.read_text() + f"\n[lab_store]\nurl = {json.dumps(url)}\n")
    return path


@pytest.mark.parametrize("query", sorted(BAD_OPTIONS))
def test_station_check_refuses_a_bad_lab_url_option_in_one_line(tmp_path, capsys, query):
    station = station_with(tmp_path, f"postgresql://bench:{SECRET}@lab-server/lab?{query}")
    assert main(["station", "check", str(station)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    shown = f"postgresql://bench:***@lab-server/lab?{query}"
    assert lines[0].startswith(f"bench: error: {station}: lab_store.url = {shown}: {BAD_OPTIONS[query]}")
    assert SECRET not in lines[0]


@pytest.mark.parametrize("query", sorted(BAD_OPTIONS))
def test_sync_refuses_the_same_option_before_connecting(tmp_path, capsys, query):
    assert main(["sync", "--store", str(tmp_path / "none.db"), "--to", f"postgresql://b:{SECRET}@h/lab?{query}"]) == 2
    line = capsys.readouterr().err.strip()
    assert line.startswith(f"bench: error: --to postgresql://b:***@h/lab?{query}: {BAD_OPTIONS[query]}")


def test_good_option_values_and_host_lists_pass(tmp_path):
    for query in (
        "sslmode=verify-full&target_session_attrs=prefer-standby&connect_timeout= 10 ",
        "ssl_min_protocol_version=tlsv1.2&ssl_max_protocol_version=TLSv1.3&channel_binding=require",
        "keepalives=+1&keepalives_idle=30&require_auth=!password,!md5",
    ):
        check_lab_url(f"postgresql://bench:{SECRET}@lab/lab?{query}")
    check_lab_url("postgresql://bench@a:5432,b/lab")  # an empty port in the list is the default (old: refused)
    assert load_station(station_with(tmp_path, "postgresql://bench@a:5433,b:5434/lab?port=")).lab_store


def libpq_refuses(url: str) -> bool:
    """Whether libpq (through psycopg) refuses ``url``'s options when asked to connect to nothing: an option
    error, not "Connection refused"."""
    try:
        psycopg.connect(url).close()
    except psycopg.ProgrammingError:
        return True
    except psycopg.OperationalError as exc:
        return "Connection refused" not in str(exc)
    raise AssertionError(f"something listens at {REFUSED}")


_CHOICE_OPTIONS = sorted(set(CHOICES) - {"sslnegotiation", "gssencmode"})  # (these two also need a server's reply)
_INTEGER_VALUES = st.sampled_from(["5", " 7 ", "+3", "x", "1.5", "0x10", "", "2147483648", "12a", "٣"])
_OPTION_VALUES = {
    **{name: st.sampled_from([*CHOICES[name], "bogus", "", CHOICES[name][0].upper()]) for name in _CHOICE_OPTIONS},
    **{name: _INTEGER_VALUES for name in INTEGER_OPTIONS if name not in ("connect_timeout", "keepalives_idle")},
    "ssl_min_protocol_version": st.sampled_from(["", "TLSv1", "tlsv1.2", "TLSv1.3", "SSLv3"]),
    "ssl_max_protocol_version": st.sampled_from(["", "TLSv1.1", "TLSv1.3", "TLSv2"]),
    "require_auth": st.sampled_from(["password", "!md5,!gss", "!md5,gss", "scram-sha-256,none", "md5,md5", "cert"]),
    "port": st.sampled_from(["1", "1,1", "1,1,1", "1,", ",1", "0", "65536", "x", " 1"]),
}


@settings(max_examples=150, deadline=None)
@given(
    options=st.dictionaries(st.sampled_from(sorted(_OPTION_VALUES)), st.none(), max_size=4).flatmap(
        lambda chosen: st.fixed_dictionaries({name: _OPTION_VALUES[name] for name in chosen})
    ),
    hosts=st.integers(1, 2),
)
@example(options={"sslmode": "bogus"}, hosts=1)
@example(options={"port": "1,"}, hosts=2)
@example(options={"keepalives_count": "0"}, hosts=1)  # refused by the socket, not by libpq's parser
def test_the_check_refuses_exactly_what_libpq_refuses(options, hosts):
    """The bundled libpq is the oracle: every generated option set that it refuses on connecting is refused by
    the check without connecting, and every set it accepts passes (connect_timeout is psycopg's to read: a float
    passes there, the check asks for the integer libpq documents; keepalives_idle < 1 is refused by the OS)."""
    options.setdefault("port", "1")
    query = "&".join(f"{name}={quote(value)}" for name, value in options.items())
    url = f"postgresql://bench:{SECRET}@{','.join(['127.0.0.1'] * hosts)}/lab?{query}"
    try:
        check_lab_url(url)
        refused = False
    except LabURLError as exc:
        refused = True
        assert SECRET not in str(exc)
    assert refused == libpq_refuses(url), url


_URL_TEXT = st.text(string.ascii_letters + string.digits + "%&=?/:@[],.+-_!~ ", max_size=40)


@settings(max_examples=300, deadline=None)
@given(
    password=st.text(string.ascii_letters + string.digits + "-_.~!", min_size=6, max_size=16),
    host=st.sampled_from(["lab", "[::1]", "[::1", "a:5432,b", "a:x", "", "a:99999", "%zz"]),
    tail=_URL_TEXT,
    in_query=st.booleans(),
)
@example(password="S3cr3t", host="lab", tail="%A0", in_query=False)  # a traceback before (UnicodeDecodeError)
def test_any_lab_url_in_a_station_is_loaded_or_refused_in_one_line_without_its_password(
    tmp_path_factory, password, host, tail, in_query
):
    url = (
        f"postgresql://bench@{host}/lab?password={password}&{tail}"
        if in_query
        else (f"postgresql://bench:{password}@{host}/{tail}")
    )
    assume(password not in url.replace(password, "", 1))  # the password appears once: where a password goes
    station = station_with(tmp_path_factory.mktemp("station"), url)
    try:
        load_station(station)
    except ConfigError as exc:  # LabURLError among them; any other exception fails the test with its traceback
        line = str(exc)
        assert "\n" not in line and password not in line
        assert line.startswith(f"{station}: lab_store.url = ")


# capsys is shared by the inputs: each reads (and so empties) it after each command
@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    password=st.text(string.ascii_letters + string.digits + "-_.~!", max_size=10).map(lambda tail: f"S3cr3t{tail}"),
    host=st.sampled_from(["lab", "[::1", "a:5432,b", "a:x", "a:0"]),
    query=st.lists(
        st.sampled_from(
            ["sslmode=bogus", "sslmode=require", "target_session_attrs=any", "port=1,2", "keepalives=x", "%A0", "x=1"]
        ),
        max_size=3,
    ),
)
@example(password="S3cr3t", host="lab/%A0", query=[])  # the database name %A0: a traceback before
def test_station_check_and_sync_print_one_line_and_never_the_password(tmp_path_factory, capsys, password, host, query):
    """Through the commands: a station file that ``bench station check`` loads (its devices then checked: exit 1
    here, none plugged in) or refuses (exit 2, one line naming ``lab_store.url``), and ``bench sync --to`` (exit 2:
    the URL refused, or the store file missing; nothing connects); no traceback, the password nowhere."""
    url = f"postgresql://bench:{password}@{host}/lab?{'&'.join(query)}"
    folder = tmp_path_factory.mktemp("station")
    station = station_with(folder, url)
    assert main(["station", "check", str(station)]) in (1, 2)
    out = capsys.readouterr()
    assert password not in out.out + out.err and "Traceback" not in out.err
    if out.err:
        assert out.err.count("\n") == 1 and out.err.startswith(f"bench: error: {station}: lab_store.url = ")
    assert main(["sync", "--store", str(folder / "none.db"), "--to", url]) == 2
    out = capsys.readouterr()
    assert password not in out.out + out.err and out.err.count("\n") == 1 and not out.out
