"""The values libpq accepts for a lab URL's options, checked without connecting: what libpq (18) itself refuses only
when a connection is tried ("invalid sslmode value", "invalid integer value ... for connection option", "could not
match 2 port numbers to 1 hosts"), so that a station file or a command's ``--to``/``--store`` is refused before a run
(one line, exit 2) rather than at sync time as "server unreachable". The keyword names themselves are checked by
libpq's parser (:func:`bench.store.lab_connection.check_lab_url`); a keyword that libpq does not know is never here.

Source: libpq's ``connectOptions2``, ``parse_int_param`` and ``sslVerifyProtocolVersion`` (PostgreSQL 18,
src/interfaces/libpq/fe-connect.c), each rule checked against the bundled libpq by tests/test_lab_url_options.py.
"""

from __future__ import annotations

import re

__all__ = ["option_problem"]

#: option -> the values libpq accepts (exactly these spellings: libpq compares them case-sensitively).
CHOICES: dict[str, tuple[str, ...]] = {
    "sslmode": ("disable", "allow", "prefer", "require", "verify-ca", "verify-full"),
    "gssencmode": ("disable", "prefer", "require"),
    "channel_binding": ("disable", "prefer", "require"),
    "target_session_attrs": ("any", "read-write", "read-only", "primary", "standby", "prefer-standby"),
    "load_balance_hosts": ("disable", "random"),
    "sslnegotiation": ("postgres", "direct"),
    "sslcertmode": ("disable", "allow", "require"),
    "min_protocol_version": ("3.0", "3.2", "latest"),
    "max_protocol_version": ("3.0", "3.2", "latest"),
}
#: protocol version -> its minor number (libpq 18: "latest" is 3.2)
_PROTOCOL_MINOR = {"3.0": 0, "3.2": 2, "latest": 2}
#: TLS versions in order (``ssl_min_protocol_version``, default TLSv1.2, and ``ssl_max_protocol_version``;
#: case-insensitive, empty = no bound).
TLS_VERSIONS = ("tlsv1", "tlsv1.1", "tlsv1.2", "tlsv1.3")
#: Options libpq reads as a C ``int`` (``parse_int_param``: blanks around an optional sign and decimal digits) ->
#: the least value it (or the socket option it sets: TCP_KEEPIDLE, TCP_KEEPINTVL, TCP_KEEPCNT) accepts; refused here
#: even with keepalives=0, where libpq leaves them unused.
INTEGER_OPTIONS: dict[str, int | None] = {
    "connect_timeout": None,
    "keepalives": None,
    "keepalives_idle": 1,
    "keepalives_interval": 1,
    "keepalives_count": 1,
    "tcp_user_timeout": None,
}
_INTEGER = re.compile(r"[ \t\n\r\f\v]*[+-]?[0-9]+[ \t\n\r\f\v]*")
_INT_RANGE = (-(2**31), 2**31 - 1)
#: ``require_auth`` methods (a comma list, all plain or all negated with ``!``, none twice).
AUTH_METHODS = ("password", "md5", "gss", "sspi", "scram-sha-256", "oauth", "none")
#: ``sslnegotiation=direct`` needs an sslmode that never falls back to plain text.
_DIRECT_SSLMODES = ("require", "verify-ca", "verify-full")


def _listed(choices: tuple[str, ...]) -> str:
    return ", ".join(choice or "''" for choice in choices)


def _integer(value: str) -> int | None:
    """``value`` as libpq's ``parse_int_param`` reads it, or None where libpq refuses it."""
    if not _INTEGER.fullmatch(value):
        return None
    number = int(value.strip())
    return number if _INT_RANGE[0] <= number <= _INT_RANGE[1] else None


def _port_problem(options: dict[str, str]) -> str | None:
    """A port list libpq refuses: a port outside 1..65535 (an empty entry means the default 5432), or a count that
    matches neither one nor the number of hosts (``host``, else ``hostaddr``: both given must count alike)."""
    ports = options["port"].split(",") if "port" in options else []
    for port in ports:
        number = _integer(port) if port.strip() else 5432
        if number is None or not 1 <= number <= 65535:
            return f"port {port!r}, expected a number from 1 to 65535"
    hosts = options["host"].split(",") if "host" in options else []
    addresses = options["hostaddr"].split(",") if "hostaddr" in options else []
    if hosts and addresses and len(hosts) != len(addresses):
        return f"{len(hosts)} hosts and {len(addresses)} hostaddr values, expected as many of each"
    servers = len(hosts or addresses) or 1
    if len(ports) > 1 and len(ports) != servers:
        return f"{len(ports)} ports for {servers} hosts, expected one port or one per host"
    return None


def _require_auth_problem(value: str) -> str | None:
    methods = value.split(",")
    negated = [method.startswith("!") for method in methods]
    names = [method.removeprefix("!") for method in methods]
    expected = f"a comma list of {_listed(AUTH_METHODS)}, all or none negated with !, none twice"
    if any(name not in AUTH_METHODS for name in names) or len(set(names)) != len(names) or len(set(negated)) > 1:
        return f"require_auth {value!r}, expected {expected}"
    return None


def option_problem(options: dict[str, str]) -> str | None:
    """What is wrong with a lab URL's options as libpq would find it on connecting, in words ("sslmode 'bogus',
    expected one of disable, ..."), or None when libpq accepts them all.

    Parameters
    ----------
    options : dict of str to str
        The URL's options as :func:`psycopg.conninfo.conninfo_to_dict` reads them (keywords known to libpq).

    Returns
    -------
    str or None
        One clause naming the option, its value and what was expected; no password is ever part of it.
    """
    for name, choices in CHOICES.items():
        if name in options and options[name] not in choices:
            return f"{name} {options[name]!r}, expected one of {_listed(choices)}"
    tls = {}
    for name, default in (("ssl_min_protocol_version", "TLSv1.2"), ("ssl_max_protocol_version", "")):
        value = options.get(name, default)
        if value and value.lower() not in TLS_VERSIONS:
            return f"{name} {value!r}, expected one of TLSv1, TLSv1.1, TLSv1.2, TLSv1.3"
        tls[name] = TLS_VERSIONS.index(value.lower()) if value else None
    low, high = tls["ssl_min_protocol_version"], tls["ssl_max_protocol_version"]
    if low is not None and high is not None and low > high:
        return "ssl_min_protocol_version above ssl_max_protocol_version, expected min <= max"
    if "min_protocol_version" in options and "max_protocol_version" in options:
        low_minor, high_minor = (
            _PROTOCOL_MINOR[options[name]] for name in ("min_protocol_version", "max_protocol_version")
        )
        if low_minor > high_minor:
            return "min_protocol_version above max_protocol_version, expected min <= max"
    for name, least in INTEGER_OPTIONS.items():
        number = _integer(options[name]) if name in options else 0
        if number is None or (least is not None and name in options and number < least):
            return f"{name} {options[name]!r}, expected an integer" + ("" if least is None else f" >= {least}")
    if options.get("sslnegotiation") == "direct" and options.get("sslmode", "prefer") not in _DIRECT_SSLMODES:
        return f"sslnegotiation 'direct' with sslmode {options.get('sslmode', 'prefer')!r}, expected sslmode " + (
            " or ".join(_DIRECT_SSLMODES)
        )
    if "require_auth" in options and (problem := _require_auth_problem(options["require_auth"])):
        return problem
    return _port_problem(options)
