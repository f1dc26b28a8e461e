"""Helpers shared by the sensor tests: a pseudo-terminal pair standing in for a serial device."""

import contextlib
import os
from collections.abc import Iterator

import serial


@contextlib.contextmanager
def pty_pair(baudrate: int = 115200) -> Iterator[tuple[int, serial.Serial]]:
    """``(master_fd, port)``: bytes written to ``master_fd`` arrive on ``port`` (a pySerial port on the slave)."""
    master, slave = os.openpty()
    port = serial.serial_for_url(os.ttyname(slave), baudrate=baudrate)
    try:
        yield master, port
    finally:
        port.close()
        os.close(master)
        os.close(slave)
