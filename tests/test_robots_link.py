"""FramedLink.write: a flush interrupted by a signal (termios.error EINTR, not an OSError) is retried; any other
termios failure is a one-line LinkError naming the port and the command."""

import errno
import termios

import pytest
import serial

from bench.errors import LinkError, LinkTimeout
from bench.robots import pkm5_wire as wire


class InterruptedFlushPort(serial.serial_for_url("loop://", timeout=0.01).__class__):
    """A loop:// port whose tcdrain fails like the kernel's: ``failures`` times with ``code``."""

    def __init__(self, failures: int, code: int) -> None:
        super().__init__("loop://", timeout=0.01)
        self.failures, self.code, self.flushes = failures, code, 0

    def flush(self) -> None:
        self.flushes += 1
        if self.flushes <= self.failures:
            raise termios.error(self.code, "Interrupted system call" if self.code == errno.EINTR else "I/O error")
        super().flush()


def test_an_interrupted_flush_is_retried_and_the_line_is_sent():
    port = InterruptedFlushPort(failures=1, code=errno.EINTR)
    link = wire.LineLink(port)
    link.write(b"ID #1*00\n", command="ID")
    assert port.flushes == 2
    assert link.read_frame(0.2, command="ID", expected="the echoed line") == b"ID #1*00"


@pytest.mark.parametrize(("failures", "code"), [(5, errno.EINTR), (1, errno.EIO)])
def test_a_flush_that_keeps_failing_is_a_link_error(failures, code):
    port = InterruptedFlushPort(failures=failures, code=code)
    link = wire.LineLink(port)
    with pytest.raises(LinkError, match=r"loop://.*cannot send 'STOP'"):
        link.write(b"STOP #2*00\n", command="STOP")
    assert port.flushes == (3 if code == errno.EINTR else 1)


def test_a_reply_split_across_reads_behind_long_noise_is_kept_whole():
    port = serial.serial_for_url("loop://", timeout=0.01)
    link = wire.LineLink(port)
    reply = wire.format_reply("OK", 7, "POS", 1, 2, 3, 4, 5, 6, "IDLE")
    noise = bytes((i * 37 + 11) % 256 for i in range(500)).replace(b"\n", b"~")
    port.write(noise + reply[:20])
    frame = link.read_frame(0.2, command="POS", expected="the noise, cut")
    assert frame == noise[: len(noise) + 20 - wire.MAX_LINE]  # all but the last MAX_LINE bytes refused
    with pytest.raises(LinkTimeout):
        link.read_frame(0.05, command="POS", expected="nothing yet")
    port.write(reply[20:])
    line = link.read_frame(0.2, command="POS", expected="the reply")
    assert wire.parse_reply(line) == wire.Reply("OK", 7, ("POS", "1", "2", "3", "4", "5", "6", "IDLE"))
