"""The PKM5 wire protocol (``docs/protocol-pkm5.md``): line encoding, checksums, command and reply parsing.

Pure functions shared by the driver (:mod:`bench.robots.pkm5`), the simulated controller
(:mod:`bench.simulators.pkm5`) and, by specification, the firmware (``firmware/pkm5/pkm5.c``).

A line is ``BODY*HH\\n``: printable ASCII, at most :data:`MAX_LINE` bytes before the newline, ``HH`` the XOR of the
body bytes in two upper-case hex digits. A command body is ``VERB [int ...] #TAG``; a reply body is
``KIND #TAG FIELD ...`` with ``KIND`` one of ``OK``, ``DONE``, ``ERR``, ``BOOT``; noise glued in front of a reply
is skipped (the checksum decides). Parsers raise only
:class:`bench.robots.link.WireProtocolError`; :func:`parse_command` raises its subclass :class:`CommandRefused`,
which carries the error code and tag the controller answers with.

The refusal rules, in the firmware's order: over :data:`MAX_LINE` bytes -> ``TOO_LONG #0``; one trailing ``\r``
dropped; an empty line is ignored; no ``*HH`` or a wrong one -> ``CHECKSUM #0`` (checked before anything else in the
body, so binary garbage and noise glued in front of a line are checksum errors); fields are split on spaces only;
the tag is trusted when exactly one field starts with ``#`` and it is ``#`` and 1-9 digits (no sign), otherwise
``SYNTAX #0``; every other refusal (non-printable byte, unknown verb, wrong arity, an argument that is not ``-`` and
1-10 digits) is ``SYNTAX`` with that tag.
"""

from __future__ import annotations

import binascii
import contextlib
import enum
from dataclasses import dataclass

from bench.robots.link import FramedLink, WireProtocolError

__all__ = [
    "AXES",
    "COMMAND_ARITY",
    "DEVICE_NAME",
    "MAX_LINE",
    "PROTOCOL_VERSION",
    "PROTOCOL_VERSIONS",
    "Command",
    "CommandRefused",
    "ErrorCode",
    "LineLink",
    "Reply",
    "checksum",
    "crc16",
    "decode_line",
    "encode_line",
    "format_command",
    "format_reply",
    "parse_command",
    "parse_reply",
]

PROTOCOL_VERSION = 1
#: Protocol versions this module speaks: 1 = XOR-8 ``*HH``, 2 = CRC-16-CCITT ``*HHHH`` (negotiated after ``ID``).
PROTOCOL_VERSIONS = (1, 2, 3)
DEVICE_NAME = "bench-pkm5"
AXES = 6
MAX_LINE = 96
_REPLY_KINDS = ("OK", "DONE", "ERR", "BOOT")

#: Number of integer arguments of each command; simulator-only commands start with ``SIM``.
COMMAND_ARITY = {
    "ID": 0,
    "POS": 0,
    "STOP": 0,
    "ENABLE": 0,
    "DISABLE": 0,
    "MOVE": AXES + 1,
    "SETPOS": AXES,
    "PROTOCOL": 1,
    "SIMLOAD": 1,
    "SIMTRUE": 0,
    "SIMLEGS": 0,
    "SIMTRACE": 4,
}


class ErrorCode(enum.IntEnum):
    """Error codes of ``ERR`` replies; the name follows the code on the wire."""

    SYNTAX = 1  # unknown verb, wrong argument count, not an integer, missing tag
    CHECKSUM = 2  # checksum missing or wrong
    TOO_LONG = 3  # line longer than MAX_LINE
    ARGUMENT = 4  # an argument out of its documented range (e.g. speed)
    LIMIT = 5  # a target outside the firmware's step limits
    DISABLED = 6  # motion requested while the drivers are disabled
    BUSY = 7  # a command that needs the robot idle arrived during a move
    STOPPED = 8  # the move was ended by STOP before reaching its target
    WATCHDOG = 9  # the link watchdog ended a move and disabled the drivers (latched: also the next command's reply)


class CommandRefused(WireProtocolError):
    """A command line the controller refuses: ``code`` and ``tag`` of its ``ERR`` reply."""

    def __init__(self, message: str, code: ErrorCode, tag: int = 0) -> None:
        super().__init__(message)
        self.code = code
        self.tag = tag


def checksum(body: bytes) -> str:
    """XOR of all bytes of ``body``, as two upper-case hex digits (NMEA 0183 style)."""
    value = 0
    for byte in body:
        value ^= byte
    return f"{value:02X}"


def crc16(body: bytes) -> str:
    """CRC-16-CCITT of ``body`` (polynomial 0x1021, initial value 0xFFFF, no reflection, no final XOR: the
    "CRC-16/CCITT-FALSE" of the CRC catalogue; check value of b"123456789" is 29B1), four upper-case hex digits.
    It detects every error of up to 3 bits, every odd number of bit errors and every burst up to 16 bits in a line
    (Koopman & Chakravarty 2004), where XOR-8 lets through about 12 % of 2-bit errors on 40-byte lines.

    ``binascii.crc_hqx`` is this CRC (CCITT polynomial, MSB first) from a given start value, in C: every line of the
    link is checked once on each side, and a Python loop over its bytes cost 9 us for a 65-byte reply."""
    return f"{binascii.crc_hqx(body, 0xFFFF):04X}"


#: Printable ASCII, 0x20-0x7E: the only bytes a line's body may hold.
_PRINTABLE = bytes(range(0x20, 0x7F))


def _check(body: bytes, version: int) -> str:
    return checksum(body) if version == 1 else crc16(body)


def encode_line(body: str, version: int = 1) -> bytes:
    """``body`` framed as ``BODY*HH\\n`` (version 1) or ``BODY*HHHH\\n`` (version 2, CRC-16)."""
    raw = body.encode("ascii")
    return raw + b"*" + _check(raw, version).encode("ascii") + b"\n"


def decode_line(line: bytes, version: int = 1) -> str:
    """The body of one line (terminator already removed; a trailing ``\\r`` is tolerated)."""
    if len(line) > MAX_LINE:
        raise CommandRefused(
            f"line of {len(line)} bytes, expected at most {MAX_LINE}: {line[:32]!r}...", ErrorCode.TOO_LONG
        )
    if line.endswith(b"\r"):
        line = line[:-1]
    digits = 2 if version == 1 else 4
    body, star, check = line[: -digits - 1], line[-digits - 1 : -digits], line[-digits:]
    if star != b"*":
        raise CommandRefused(f"line {line!r} has no '*{'H' * digits}' checksum", ErrorCode.CHECKSUM)
    if check != _check(body, version).encode("ascii"):
        raise CommandRefused(
            f"line {line!r}: checksum {check!r}, expected {_check(body, version)!r}", ErrorCode.CHECKSUM
        )
    if body.translate(None, _PRINTABLE):  # anything left once the printable bytes are deleted
        raise CommandRefused(f"line {line!r} has bytes outside printable ASCII", ErrorCode.SYNTAX, _trusted_tag(body))
    return body.decode("ascii")


def _fields(body: bytes | str) -> list:
    """Fields separated by spaces (only spaces: a tab is part of a field, as in the firmware)."""
    return [t for t in body.split(b" " if isinstance(body, bytes) else " ") if t]


def _trusted_tag(body: bytes) -> int:
    """The tag of a checksummed body: exactly one field starts with '#' and it is '#' + 1-9 digits; else 0."""
    tags = [t for t in _fields(body) if t.startswith(b"#")]
    if len(tags) == 1 and 1 <= len(tags[0]) - 1 <= 9 and all(0x30 <= b <= 0x39 for b in tags[0][1:]):
        return int(tags[0][1:])
    return 0


def _split_tag(tokens: list[str], line: object) -> tuple[list[str], int]:
    tags = [t for t in tokens if t.startswith("#")]
    if len(tags) != 1:
        raise WireProtocolError(f"line {line!r}: expected exactly one '#TAG' field")
    digits = tags[0][1:]
    if not (digits.isascii() and digits.isdigit()) or len(digits) > 9:
        raise WireProtocolError(f"line {line!r}: tag {tags[0]!r}, expected '#' and 1-9 digits")
    return [t for t in tokens if t is not tags[0]], int(digits)


def _parse_int(token: str, line: object) -> int:
    body = token[1:] if token[:1] == "-" else token
    if not (body.isascii() and body.isdigit()) or len(body) > 10:
        raise WireProtocolError(f"line {line!r}: {token!r} is not a decimal integer")
    return int(token)


@dataclass(frozen=True)
class Command:
    """One PC -> controller command."""

    verb: str
    args: tuple[int, ...]
    tag: int


def format_command(verb: str, args: tuple[int, ...] | list[int], tag: int, version: int = 1) -> bytes:
    """Encode a command line; the arity is checked so that a driver cannot emit a malformed command."""
    if COMMAND_ARITY.get(verb) != len(args):
        raise ValueError(f"command {verb!r} with {len(args)} arguments, expected {COMMAND_ARITY.get(verb)}")
    return encode_line(" ".join([verb, *(str(int(a)) for a in args), f"#{int(tag)}"]), version)


def parse_command(line: bytes, version: int = 1) -> Command:
    """Decode a command line (the controller side)."""
    tokens = _fields(decode_line(line, version))
    try:
        tokens, tag = _split_tag(tokens, line)
    except WireProtocolError as exc:
        raise CommandRefused(str(exc), ErrorCode.SYNTAX) from None
    if not tokens or tokens[0] not in COMMAND_ARITY:
        raise CommandRefused(
            f"line {line!r}: unknown command, expected one of {sorted(COMMAND_ARITY)}", ErrorCode.SYNTAX, tag
        )
    verb, args = tokens[0], tokens[1:]
    if len(args) != COMMAND_ARITY[verb]:
        raise CommandRefused(
            f"line {line!r}: {verb} takes {COMMAND_ARITY[verb]} arguments, got {len(args)}", ErrorCode.SYNTAX, tag
        )
    try:
        return Command(verb, tuple(_parse_int(a, line) for a in args), tag)
    except WireProtocolError as exc:
        raise CommandRefused(str(exc), ErrorCode.SYNTAX, tag) from None


@dataclass(frozen=True)
class Reply:
    """One controller -> PC reply: ``kind`` (OK/DONE/ERR/BOOT), ``tag`` and the remaining ``fields``."""

    kind: str
    tag: int
    fields: tuple[str, ...]

    def ints(self, start: int, count: int) -> tuple[int, ...]:
        """``count`` integer fields from ``start``; a short or non-integer reply raises WireProtocolError."""
        chunk = self.fields[start : start + count]
        if len(chunk) != count:
            raise WireProtocolError(f"reply {self}: expected {count} integers from field {start}")
        return tuple(_parse_int(t, self) for t in chunk)


def format_reply(kind: str, tag: int, *fields: object, version: int = 1) -> bytes:
    return encode_line(" ".join([kind, f"#{int(tag)}", *(str(f) for f in fields)]), version)


def parse_reply(line: bytes, version: int = 1) -> Reply:
    """Decode a reply line (the PC side).

    Noise glued in front of a reply (a glitch with no newline) is skipped: if the whole line fails, the last
    ``KIND #`` start whose checksum verifies is taken; otherwise the first error is raised.
    """
    try:
        return _parse_reply(line, version)
    except WireProtocolError:
        starts = [line.rfind(kind.encode("ascii") + b" #") for kind in _REPLY_KINDS]
        start = max(starts)
        if start > 0:
            with contextlib.suppress(WireProtocolError):
                return _parse_reply(line[start:], version)
        raise


def _parse_reply(line: bytes, version: int) -> Reply:
    tokens = _fields(decode_line(line, version))
    if not tokens or tokens[0] not in _REPLY_KINDS:
        raise WireProtocolError(f"line {line!r}: expected a reply starting with one of {_REPLY_KINDS}")
    fields, tag = _split_tag(tokens[1:], line)
    return Reply(tokens[0], tag, tuple(fields))


class LineLink(FramedLink):
    """Newline framing: a frame is everything up to ``\\n``.

    A run of bytes without a newline longer than ``4 * MAX_LINE`` (line noise) is cut and handed over to be
    refused, all but its last ``MAX_LINE`` bytes: those may be the start of a valid line split across reads (a
    reply arriving behind the noise), and are kept so that the line is whole once its newline comes."""

    def _take_frame(self) -> bytes | None:
        end = self._pending.find(b"\n")
        if end < 0:
            if len(self._pending) > 4 * MAX_LINE:  # noise: refuse what can never be part of a valid line
                cut = len(self._pending) - MAX_LINE
                frame = bytes(self._pending[:cut])
                del self._pending[:cut]
                return frame
            return None
        frame = bytes(self._pending[:end])
        del self._pending[: end + 1]
        return frame
