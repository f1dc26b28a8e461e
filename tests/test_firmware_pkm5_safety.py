"""The pkm5 firmware's safety chain on the emulated ATmega2560, in the harness's script mode: host lines placed at
exact emulated times, so each case is deterministic whatever the load of the test machine (issue 31, items 6-9).
The promise checked (docs/firmware.md, "Link watchdog"): the enable pins reach the disabled level at most 250 ms of
emulated time after the last valid host command line, whatever else arrives. Skipped, with the reason, where
gcc-avr / avr-libc / simavr are not installed."""

import random

import pytest

from bench.robots import pkm5_wire as wire
from tests.firmware_sim import DRIVERS_ENABLED_LEVEL, build, needs_toolchain, run_script

pytestmark = needs_toolchain
LIMIT_S = 0.250
HOST_VERBS = set(wire.COMMAND_ARITY)
FAR = "MOVE 10000 10000 10000 10000 20000 20000 1000"  # 9.2 s at 1000 steps/s: the watchdog ends it


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    return build(tmp_path_factory)


class Host:
    """Host lines at emulated times on a CRC-16 (version 2) link with the drives enabled."""

    def __init__(self):
        self.tag = 0
        self.lines = [(0.010, self.frame("ID", 1)), (0.020, self.frame("PROTOCOL 2", 1))]

    def frame(self, body, version=2):
        self.tag += 1
        return wire.encode_line(f"{body} #{self.tag}", version)

    def send(self, t_s, body, version=2):
        self.lines.append((t_s, self.frame(body, version)))

    def move_with_heartbeats(self, start_s, until_s, move=FAR):
        """ENABLE, a long MOVE, then a POS every 50 ms up to ``until_s``."""
        self.send(start_s, "ENABLE")
        self.send(start_s + 0.01, move)
        t = start_s + 0.06
        while t <= until_s + 1e-9:
            self.send(t, "POS")
            t += 0.05
        return t - 0.05


def host_lines(edges):
    """Emulated times of the valid host command lines the MCU received (either framing, a host verb)."""
    out = []
    for e in edges:
        if e.kind != "RX":
            continue
        for version in (2, 1):
            try:
                body = wire.decode_line(e.line, version)
            except wire.WireProtocolError:
                continue
            if body.split(" ")[0] in HOST_VERBS:
                out.append(e.t_s)
            break
    return out


def powered_after(edges, t_s):
    """Seconds from ``t_s`` until all six enable pins are at the disabled level (inf: never)."""
    level = {}
    for e in edges:
        if e.kind == "EN":
            level[e.axis] = e.level
            if e.t_s >= t_s and len(level) == 6 and DRIVERS_ENABLED_LEVEL not in level.values():
                return e.t_s - t_s
    return float("inf")


def replies(edges):
    out = []
    for e in edges:
        if e.kind == "TX":
            for version in (2, 1):
                try:
                    out.append(wire.decode_line(e.line, version))
                    break
                except wire.WireProtocolError:
                    pass
    return out


def test_a_silent_host_mid_move_loses_the_drives_within_250_ms(built, tmp_path):
    host = Host()
    host.move_with_heartbeats(0.05, 0.5)
    edges = run_script(built, tmp_path / "events.txt", host.lines, 1.2)
    last = host_lines(edges)[-1]
    assert powered_after(edges, last) < LIMIT_S
    assert not [e for e in edges if e.kind == "STEP" and e.t_s > last + LIMIT_S]
    assert any(r.startswith("ERR #4 9 WATCHDOG") for r in replies(edges))


def test_a_stop_during_the_ramp_down_keeps_the_trip_and_the_next_move_is_watched(built, tmp_path):
    """Item 6: a STOP 170 ms after the last heartbeat (the ramp-down runs 150-190 ms) must not clear the trip."""
    host = Host()
    last = host.move_with_heartbeats(0.05, 0.5)
    host.send(last + 0.170, "STOP")
    host.send(0.9, "POS")  # answered by the latched fault
    host.move_with_heartbeats(1.0, 1.2, "MOVE 800 800 800 800 1600 1600 1000")  # back home, then silence
    edges = run_script(built, tmp_path / "events.txt", host.lines, 2.5)
    said = replies(edges)
    assert any(r.startswith("ERR #4 9 WATCHDOG") for r in said), said  # not a plain STOPPED
    beats = host_lines(edges)
    before_stop = max(t for t in beats if t < 0.6)
    assert powered_after(edges, before_stop) < LIMIT_S
    assert powered_after(edges, beats[-1]) < LIMIT_S


@pytest.mark.parametrize("babble_s", [0.75, 2.0])
def test_babble_of_short_invalid_lines_does_not_feed_the_watchdog(built, tmp_path, babble_s):
    """Item 7: a stream of short invalid lines after the last heartbeat (11520 bytes/s at 115200 baud)."""
    host = Host()
    host.move_with_heartbeats(0.05, 0.5)
    host.lines.append((0.51, b"x\n" * int(babble_s * 11520 / 2)))
    edges = run_script(built, tmp_path / "events.txt", host.lines, 0.5 + babble_s + 0.5)
    last = host_lines(edges)[-1]
    assert powered_after(edges, last) < LIMIT_S


def test_replies_echoed_back_are_no_heartbeat(built, tmp_path):
    """Item 8: a terminal in echo mode returns the firmware's own replies, valid CRC and all."""
    host = Host()
    host.move_with_heartbeats(0.05, 0.5)
    echo = wire.encode_line("OK #9 POS 1000 1000 1000 1000 2000 2000 MOVING", 2)
    host.lines += [(0.5 + 0.05 * k, echo) for k in range(1, 20)]
    edges = run_script(built, tmp_path / "events.txt", host.lines, 1.6)
    last = host_lines(edges)[-1]
    assert powered_after(edges, last) < LIMIT_S


def truncated_crc_id():
    """A CRC-16 ``ID`` line that, with its last two hex digits lost, verifies as an XOR-8 line (1 tag in 256)."""
    for tag in range(1, 100000):
        body = f"ID #{tag}"
        line = wire.encode_line(body, 2)
        if line[:-3] + b"\n" == wire.encode_line(body, 1):
            return line[:-3] + b"\n"
    raise AssertionError("no such tag")


def test_a_crc_line_that_lost_two_characters_does_not_downgrade_the_link(built, tmp_path):
    """Item 9: once CRC-16 framing is on, the link never goes back to XOR-8 (refused, answered in CRC-16)."""
    host = Host()
    host.lines.append((0.05, truncated_crc_id()))
    host.send(0.10, "POS")
    host.send(0.15, "PROTOCOL 1")
    host.send(0.20, "POS")
    edges = run_script(built, tmp_path / "events.txt", host.lines, 0.3)
    said = [e.line for e in edges if e.kind == "TX"]
    assert wire.decode_line(said[-4], 2) == "ERR #0 2 CHECKSUM"
    assert wire.decode_line(said[-3], 2).startswith("OK #3 POS")
    assert wire.decode_line(said[-2], 2) == "ERR #4 4 ARGUMENT"
    assert wire.decode_line(said[-1], 2).startswith("OK #5 POS")


def random_kills(count, seed):
    """``count`` moves, each killed (the host falls silent) at a random time; a new host clears the fault. Returns
    the host, (when each MOVE was sent, when its host fell silent), and the end time."""
    rng = random.Random(seed)
    host, t, kills = Host(), 0.05, []
    for _ in range(count):
        host.send(t, "ID")  # clears a latched fault (answered ERR 9)
        host.send(t + 0.005, "ENABLE")
        host.send(t + 0.010, f"MOVE {rng.randrange(0, 10560)} 800 800 800 1600 1600 {rng.randrange(200, 1001)}")
        kill = t + 0.010 + rng.uniform(0.0, 0.4)
        beat = t + 0.060
        while beat < kill:
            host.send(beat, "POS")
            beat += 0.05
        kills.append((t + 0.010, kill))
        t = kill + 0.5
    return host, kills, t


def kill_drill(built, events, count, seed):
    """Worst time, s, from each kill's last host line to the drives' disabled level (inf: not disabled)."""
    host, kills, end_s = random_kills(count, seed)
    edges = run_script(built, events, host.lines, end_s)
    beats = host_lines(edges)
    done = [e.t_s for e in edges if e.kind == "TX" and e.line.startswith(b"DONE")]
    worst, watched = 0.0, 0
    for move, kill in kills:
        last = max(t for t in beats if t <= kill + 0.01)
        if not [t for t in done if move < t < kill + 0.5]:  # a move that ended (DONE) keeps its drives at rest
            worst = max(worst, powered_after(edges, last))
            watched += 1
    return worst, watched


@pytest.mark.slow
def test_random_host_kills_disable_the_drives_within_250_ms(built, tmp_path):
    """Item (d): 40 random kills in one emulated run (tools/pkm5_kill_drill.py runs more)."""
    worst, watched = kill_drill(built, tmp_path / "events.txt", 40, seed=31)
    assert watched > 20 and worst < LIMIT_S


def test_a_move_resent_with_its_tag_is_answered_not_executed_again(built, tmp_path):
    """Item 12 (protocol 3): the driver re-sends a MOVE whose OK it did not get; the firmware answers it again (and,
    once it has ended, its end) without a second execution: the STEP edges are one move's."""
    host = Host()
    host.lines[-1] = (0.020, host.frame("PROTOCOL 3", 1))
    host.send(0.03, "ENABLE", 3)
    move = host.frame("MOVE 900 800 800 800 1600 1600 1000", 3)
    host.lines += [(0.04, move), (0.06, move)]
    for k in range(6):
        host.send(0.1 + 0.05 * k, "POS", 3)  # heartbeats: the move takes 316 ms
    host.lines.append((0.40, move))
    edges = run_script(built, tmp_path / "events.txt", host.lines, 0.6)
    said = [r for r in replies(edges) if " #5 " in r]
    assert said == [
        "OK #5 MOVE 316",
        "OK #5 MOVE 316",
        "DONE #5 900 800 800 800 1600 1600",
        "OK #5 MOVE 316",
        "DONE #5 900 800 800 800 1600 1600",
    ]
    assert sum(1 for e in edges if e.kind == "STEP" and e.level == 1) == 100
