"""Issue 31 item 12: the driver against the simulated controller through a line that corrupts 5 % and 10 % of the
frames in each direction (bench.simulators.noisy_link): every move completes or is stopped, no MOVE is executed
twice although the driver re-sends unacknowledged ones (protocol 3: the controller answers a MOVE re-sent with its
tag without executing it again), and every stop() from another thread ends the move it was meant for.
benchmarks/bench_pkm5_corrupted_frames.py runs the same drill at a larger size."""

import logging

import numpy as np
import pytest

from bench.robots import pkm5_wire as wire
from bench.simulators.noisy_link import corrupted_frames_drill
from bench.simulators.pkm5 import Pkm5SimDevice


@pytest.mark.slow
@pytest.mark.parametrize("rate", [0.05, 0.10])
def test_corrupted_frames_both_ways_execute_no_move_twice_and_lose_no_stop(rate, caplog):
    caplog.set_level(logging.ERROR)
    result = corrupted_frames_drill(rate, 60, seed=31)
    assert result.failed == 0, result.failures
    assert result.executed_twice == 0 and result.lost_stops == 0
    assert result.completed + result.stopped == 60 and result.stops == 15
    assert result.corrupted["to_controller"] > 0 and result.corrupted["to_host"] > 0


def test_a_move_resent_with_its_tag_is_answered_not_executed_again():
    device = Pkm5SimDevice(lambda steps, load_kg: np.zeros(5), speed_factor=1.0)
    device.tick(0.0)
    for body in ("PROTOCOL 3 #1",):
        device.feed(wire.encode_line(body), 0.0)
    for body in ("ENABLE #2", "MOVE 900 900 900 900 1700 1700 100 #3"):
        device.feed(wire.encode_line(body, 3), 0.0)
    again = device.feed(wire.encode_line("MOVE 900 900 900 900 1700 1700 100 #3", 3), 0.5)
    assert [wire.decode_line(line, 3) for line in again.splitlines()] == ["OK #3 MOVE 1000"]
    device.tick(2.0)  # the move ends
    again = device.feed(wire.encode_line("MOVE 900 900 900 900 1700 1700 100 #3", 3), 2.5)
    assert [wire.decode_line(line, 3) for line in again.splitlines()] == [
        "OK #3 MOVE 1000",
        "DONE #3 900 900 900 900 1700 1700",
    ]
    assert device.started_moves == [3]
    fresh = device.feed(wire.encode_line("MOVE 900 900 900 900 1700 1700 100 #4", 3), 3.0)  # a new tag: executed
    assert wire.decode_line(fresh.splitlines()[0], 3) == "OK #4 MOVE 0" and device.started_moves == [3, 4]
