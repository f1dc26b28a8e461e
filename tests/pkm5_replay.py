"""One script of raw PC -> controller lines, replayed against the firmware (emulated) and the simulator
(tests/test_firmware_replay.py). Each step is (raw bytes, masked): ``masked`` marks the steps whose replies carry
timing fields (a move's duration, live positions), compared with those numbers blanked."""

from bench.robots.pkm5_wire import checksum, encode_line


def _lower_hex(body: str) -> bytes:
    check = checksum(body.encode())
    assert check != check.lower(), "pick a body whose checksum has a hex letter"
    return body.encode() + b"*" + check.lower().encode() + b"\n"


def _padded(body_length: int) -> bytes:
    """A valid ``POS`` line whose body is ``body_length`` bytes (the line is 3 bytes longer)."""
    return encode_line("POS" + " " * (body_length - 3 - 3) + "#12")


SCRIPT = [
    (b"\n", False),  # empty line: ignored
    (encode_line("ID #1"), False),
    (encode_line("POS #2"), False),
    (b"POS #3*00\n", False),  # bad checksum
    (_lower_hex("POS #3"), False),  # lower-case hex digits
    (b"POS #4\n", False),  # no checksum
    (b"\xf2\x01\x80garbage \xff*ZZ\n", False),  # binary garbage, wrong *HH
    (encode_line("\x01\x02 #5"), False),  # non-printable body with a valid checksum
    (b"\x13\x37xx" + encode_line("POS #6"), False),  # noise glued before a valid line
    (encode_line("MOVE 1 2 3 4 5 6 7 8 9 #7"), False),  # too many tokens
    (encode_line("MOVE 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 #7"), False),
    (b"Q" * 200 + b"\n", False),  # over-long
    (_padded(93), False),  # exactly 96 bytes: accepted
    (_padded(94), False),  # 97 bytes: too long
    (encode_line("POS #11")[:-1] + b"\r\n", False),  # CRLF
    (encode_line("POS #0"), False),  # tags of every size and sign
    (encode_line("POS #9"), False),
    (encode_line("POS #999999999"), False),
    (encode_line("POS #1000000000"), False),
    (encode_line("POS #99999999999"), False),
    (encode_line("POS #+5"), False),
    (encode_line("POS #-5"), False),
    (encode_line("POS #007"), False),
    (encode_line("POS #"), False),
    (encode_line("POS #1 #2"), False),
    (encode_line("POS #x #13"), False),
    (encode_line("POS"), False),
    (encode_line("ID\t#14"), False),  # a tab is not a separator
    (encode_line("pos #15"), False),
    (encode_line("JUMP #16"), False),
    (encode_line("ID 5 #17"), False),
    (encode_line("SETPOS +800 800 800 800 1600 1600 #18"), False),
    (encode_line("SETPOS 9999999999 800 800 800 1600 1600 #19"), False),
    (encode_line("SETPOS 99999999999 800 800 800 1600 1600 #20"), False),
    (encode_line("SETPOS -1 800 800 800 1600 1600 #21"), False),
    (encode_line("SETPOS -0 800 800 800 1600 1600 #22"), False),
    (encode_line("MOVE 1000 800 800 800 1600 1600 200 #23"), False),  # disabled
    (encode_line("ENABLE #24"), False),
    (encode_line("MOVE 1000 800 800 800 1600 1600 0 #25"), False),  # speed out of range
    (encode_line("MOVE 1000 800 800 800 1600 1600 1001 #26"), False),
    (encode_line("MOVE 99999 800 800 800 1600 1600 200 #27"), False),  # limit
    (encode_line("SIMPLE #28"), False),
    (encode_line("MOVE 1800 800 800 800 1600 1600 100 #30"), True),  # 10 s move
    (encode_line("MOVE 900 800 800 800 1600 1600 100 #31"), False),  # BUSY during a move
    (encode_line("SETPOS 1 2 3 4 5 6 #32"), False),
    (encode_line("ENABLE #33"), False),
    (encode_line("DISABLE #34"), False),
    (encode_line("POS #35"), True),
    (encode_line("STOP #36"), True),  # STOP mid-move
    (encode_line("STOP #37"), True),  # where it stopped
    (encode_line("SETPOS 1000 1000 1000 1000 2000 2000 #38"), False),
    (encode_line("POS #39"), False),
    (encode_line("MOVE 1000 1000 1000 1000 2000 2000 500 #40"), False),  # already there
    (encode_line("DISABLE #41"), False),
    (encode_line("POS #42"), False),
    (encode_line("PROTOCOL 4 #50"), False),  # protocol v2: negotiation (4: none such)
    (encode_line("PROTOCOL 2 #51"), False),  # answered in v1, then CRC-16 both ways
    (encode_line("ID #52", 2), False),
    (encode_line("POS #53"), False),  # a v1 line on a v2 link: CHECKSUM
    (encode_line("POS #54", 2)[:-3] + b"00\n", False),  # bad CRC
    (encode_line("POS #55", 2).lower(), False),
    (b"\x13\x37" + encode_line("POS #56", 2), False),  # noise glued in front
    (encode_line("MOVE 1 2 3 #57", 2), False),
    (encode_line("POS #58 #59", 2), False),
    (b"Q" * 97 + b"\n", False),
    (encode_line("ID #60"), False),  # a v1 ID does not downgrade a v2 link
    (encode_line("PROTOCOL 1 #61", 2), False),  # nor does PROTOCOL 1: ARGUMENT
    (encode_line("POS #62", 2), False),
]
