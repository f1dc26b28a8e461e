"""Dry-run duration: a streamed capture (an ``arrival``) takes its hold window in real time, every other capture
``CAPTURE_S``; the estimate is the sum of moves, settles, captures and prompts at real speed."""

from __future__ import annotations

import pytest

from bench.protocols.iso9283 import StabilisationOvershoot
from bench.protocols.plan import CAPTURE_S, capture_s, summarize
from bench.steps import Capture

POSES = {"A": [100.0, -10.0, 310.0], "B": [120.0, 10.0, 330.0]}


def test_an_arrival_capture_takes_its_hold_window_and_a_static_capture_the_default():
    assert capture_s(Capture("P1", 1, kind="arrival", conditions={"lead_s": 1.0, "hold_s": 3.0})) == 3.0
    assert capture_s(Capture("P1", 1, conditions={"velocity_pct": 100.0})) == CAPTURE_S


@pytest.mark.parametrize("hold_s", [0.5, 4.0])
def test_the_estimate_counts_every_hold_window_of_a_stabilisation_run(hold_s):
    summary = summarize(StabilisationOvershoot(cycles=3, lead_s=1.0, hold_s=hold_s, poses=POSES))
    assert summary.counts["captures"] == 6
    assert summary.capture_s == pytest.approx(6 * hold_s)
    assert summary.estimated_s == pytest.approx(summary.move_s + summary.settle_s + summary.prompt_s + 6 * hold_s)
    assert summary.move_s > 0 and f"captures 0:00:{round(6 * hold_s):02d}" in summary.lines()[1]


def test_a_longer_hold_lengthens_the_estimate_by_exactly_the_added_hold_time():
    short, long = (summarize(StabilisationOvershoot(cycles=2, hold_s=h, poses=POSES)) for h in (1.0, 3.0))
    assert long.move_s == short.move_s
    assert long.estimated_s - short.estimated_s == pytest.approx(4 * 2.0)


def test_the_dry_run_warns_when_the_payload_reaches_the_documented_failure_load():
    """000 §8.7.5: the structure failed on reloading at 25 kg; the shipped example stays below it, the dissertation's
    own ladder (top rung 25.23 kg) is warned about before anything moves."""
    from bench.metrology.documents import LADDER_KG, PAYLOAD_FAILURE_KG
    from bench.protocols.base import load_protocol
    from bench.protocols.dissertation import PayloadLadder

    example = summarize(load_protocol("examples/payload_ladder.toml"))
    assert example.warnings == () and not any(line.startswith("WARNING") for line in example.lines())
    ladder = summarize(PayloadLadder(loads_kg=LADDER_KG))
    (warning,) = ladder.warnings
    assert "25.23 kg" in warning and f"failure load {PAYLOAD_FAILURE_KG:g} kg" in warning
    assert f"WARNING: {warning}" in ladder.lines()
