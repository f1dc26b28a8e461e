"""The lab store's address and connection: what a ``postgresql://`` URL may be, its one-line errors with the password
hidden, and :func:`connect` (psycopg 3), which tells bad input (exit 2) from the server's side (exit 1) and a crowded
server (:class:`LabServerBusy`, waited for by the sync) apart. See docs/lab-store.md."""

from __future__ import annotations

import re
from typing import Any

from bench.errors import BenchError, ConfigError
from bench.store.lab_url_options import option_problem

__all__ = [
    "LabServerBusy",
    "LabStoreError",
    "LabURLError",
    "check_lab_url",
    "connect",
    "is_lab_url",
    "one_line",
    "psycopg_module",
    "redacted",
]


class LabStoreError(BenchError):
    """The lab store cannot be reached or used (credentials, server, schema); the local data is untouched."""

    exit_code = 1


class LabServerBusy(LabStoreError):
    """The server has no connection slot free now (more benches at once than its ``max_connections``): a sync
    waits a jittered, growing while and tries again (:func:`sync_store`), never counting it as a lost connection."""


class LabURLError(ConfigError):
    """A lab store address that is not a usable PostgreSQL URL (bad input, exit 2)."""


def is_lab_url(spec: str) -> bool:
    """True for a ``postgresql://`` (or ``postgres://``) store address rather than a file."""
    return str(spec).startswith(("postgresql://", "postgres://"))


#: ``scheme://user:PASSWORD@`` and ``password=VALUE`` (a query parameter or a conninfo keyword): what
#: :func:`redacted` hides. The user part stops at the first ``:``; the password runs to the last ``@`` (an unencoded
#: ``@`` in a password hides a little more, never less), wherever such a URL stands in the text.
_PASSWORD_PARTS = (
    re.compile(r"([A-Za-z][A-Za-z0-9+.-]*://[^:/@?#\s\"']*):[^\s\"']*@"),
    re.compile(r"(?i)\b(password=)[^&\s]*"),
)
#: libpq's own checks of an option's value ("invalid sslmode value", "invalid port number"; "invalid integer value
#: ... for connection option" comes after the host it was trying: ``keepalives=x``): a bad URL, not an unreachable
#: server.
_BAD_OPTION = re.compile(r'^(connection is bad: )?invalid |: invalid [\w ]+ value ".*" for connection option ')


#: What the server (or its socket's full listen queue: EAGAIN) says when it has no connection slot free now.
_BUSY = (
    "too many clients",
    "too many connections for role",
    "remaining connection slots are reserved",
    "Resource temporarily unavailable",
)


def redacted(url: str) -> str:
    """``url`` with its password (user info or ``password=`` parameter) replaced by ``***``, for messages; never
    fails, whatever the text (a malformed URL is shown redacted too)."""
    shown = _PASSWORD_PARTS[0].sub(r"\1:***@", str(url))
    return _PASSWORD_PARTS[1].sub(r"\1***", shown)


def check_lab_url(url: str, option: str = "lab store") -> None:
    """Refuse, in one :class:`LabURLError` line with the password hidden, a lab store address that is not a
    well-formed PostgreSQL URL: another scheme, a malformed host, an unknown parameter, a value libpq would refuse
    on connecting (``sslmode=bogus``, a port out of range: :func:`option_problem`). Nothing is connected to."""
    shown = redacted(url)
    if not is_lab_url(url):
        raise LabURLError(f"{option} {shown}: expected a postgresql://USER:PASSWORD@HOST/DBNAME URL")
    psycopg = psycopg_module()
    try:
        options = psycopg.conninfo.conninfo_to_dict(url)
    except psycopg.ProgrammingError as exc:
        raise LabURLError(f"{option} {shown}: not a valid PostgreSQL URL ({redacted(one_line(exc))})") from None
    except UnicodeDecodeError:  # psycopg decodes libpq's reading of a %-escape such as %A0 as UTF-8
        raise LabURLError(f"{option} {shown}: not a valid PostgreSQL URL (a %-escape that is not UTF-8 text)") from None
    problem = option_problem(options)
    if problem is not None:
        raise LabURLError(f"{option} {shown}: {redacted(problem)}")


def psycopg_module() -> Any:
    """psycopg 3, or the one-line error saying how to install the lab-store extra."""
    from bench.extras import require

    return require("psycopg")


def one_line(exc: BaseException) -> str:
    """The first non-empty line of ``exc``'s message (libpq's are several lines), or its type's name."""
    lines = [line.strip() for line in str(exc).splitlines() if line.strip()]
    return lines[0] if lines else type(exc).__name__


def connect(url: str, *, connect_timeout_s: int = 5) -> Any:
    """An open psycopg connection to ``url``; :class:`LabStoreError` says in one line what is wrong."""
    check_lab_url(url)
    psycopg = psycopg_module()
    shown = redacted(url)
    # the URL's own connect_timeout wins (a keyword argument would silently replace it, a bad one too)
    own_timeout = "connect_timeout" in psycopg.conninfo.conninfo_to_dict(url)
    try:
        return psycopg.connect(url, **({} if own_timeout else {"connect_timeout": connect_timeout_s}))
    except psycopg.ProgrammingError as exc:  # psycopg's own reading of a value: "bad value for connect_timeout"
        raise LabURLError(f"lab store {shown}: not a usable PostgreSQL URL ({redacted(one_line(exc))})") from None
    except psycopg.OperationalError as exc:
        detail = redacted(one_line(exc))
        if _BAD_OPTION.search(detail):
            raise LabURLError(f"lab store {shown}: not a usable PostgreSQL URL ({detail})") from None
        if "password authentication failed" in detail or "no password supplied" in detail:
            raise LabStoreError(f"lab store {shown}: bad credentials ({detail})") from exc
        if any(words in detail for words in _BUSY):
            raise LabServerBusy(f"lab store {shown}: server busy, no connection slot free ({detail})") from exc
        if "does not exist" in detail:
            raise LabStoreError(f"lab store {shown}: {detail}") from exc
        raise LabStoreError(f"lab store {shown}: server unreachable ({detail})") from exc
