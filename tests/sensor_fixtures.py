"""Fixtures shared by the sensor tests: a pseudo-terminal pair standing in for a serial device."""

import os

import pytest
import serial


@pytest.fixture
def pty_port():
    """``(master_fd, port)``: bytes written to ``master_fd`` arrive on ``port`` (a pySerial port on the slave)."""
    master, slave = os.openpty()
    port = serial.serial_for_url(os.ttyname(slave), baudrate=115200)
    yield master, port
    port.close()
    os.close(master)
    os.close(slave)
