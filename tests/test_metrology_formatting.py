"""One rounding rule for every output: U to two significant digits, the value to the same decimal place."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bench.metrology.formatting import (
    format_measured,
    format_pair,
    format_value,
    natural_key,
    pose_label,
    report_order,
    uncertainty_decimals,
)


@pytest.mark.parametrize(
    "value, u, text",
    [
        (0.44051, 0.23432, "0.44 ± 0.23"),  # the 0.4405 ± 0.2343
        (100.02147, 0.00035, "100.02147 ± 0.00035"),  # GUM 7.2.2: m_S = 100.021 47 g, u = 0.35 mg
        (0.44, 0.0996, "0.44 ± 0.10"),  # U rounds up into the next decade: two digits of 0.10
        (123.4, 9.96, "123 ± 10"),
        (1234.0, 56.0, "1234 ± 56"),
        (12345.0, 678.0, "12350 ± 680"),  # U's second digit is the tens: the value to the tens, half up
        (-0.0001, 0.02, "0.000 ± 0.020"),  # no "-0.000"
        (1.0, 1.0, "1.0 ± 1.0"),
    ],
)
def test_hand_rounded_cases(value, u, text):
    assert format_measured(value, u) == text


def test_without_an_uncertainty_three_decimals():
    assert format_pair(0.5, 0.0) == ("0.500", "0.000")
    # a U of 0 (RP of 2 cycles) is no uncertainty: said so, never "± 0.000"
    assert format_measured(0.5, 0.0) == "0.500 (U not determined)"
    assert format_measured(0.5, float("nan")) == "0.500 (U not determined)"
    assert uncertainty_decimals(float("nan")) == 3


def test_signed_values():
    assert format_value(0.912, 0.25, signed=True) == "+0.91"
    assert format_value(-0.88, 0.25, signed=True) == "-0.88"
    assert format_value(0.001, 0.25, signed=True) == "0.00"


@given(st.floats(-1e4, 1e4), st.floats(1e-6, 1e3))
def test_u_has_two_significant_digits_and_the_value_its_decimal_place(value, u):
    shown, shown_u = format_pair(value, u)
    assert float(shown_u) == pytest.approx(u, rel=0.051)  # at most half a unit of the second digit
    places = uncertainty_decimals(u)
    assert len(shown.partition(".")[2]) == len(shown_u.partition(".")[2]) == max(places, 0)
    assert abs(float(shown) - value) <= 0.5 * 10.0**-places * (1 + 1e-9) + 1e-9 * abs(value)
    digits = shown_u.replace(".", "").lstrip("0")
    assert len(digits.rstrip("0") if places < 0 else digits) in (1, 2)  # "0.10" keeps its trailing zero
    assert math.floor(math.log10(float(shown_u))) - (-places) in (0, 1)


def test_labels_read_as_words():
    assert pose_label("P1", (("velocity_pct", 100.0),)) == "P1, 100 % velocity"
    assert pose_label("P3", (("velocity_pct", 50.0), ("load_kg", 2.5))) == "P3, 50 % velocity, 2.5 kg load"
    assert pose_label("P2") == "P2"


def test_report_order_keeps_the_condition_order_and_sorts_poses_naturally():
    cycle = ["P1", "P5", "P4", "P3", "P2", "P10"]
    poses = [SimpleNamespace(pose=p, conditions=(("velocity_pct", v),)) for v in (100.0, 10.0) for p in cycle]
    ordered = [(p.conditions[0][1], p.pose) for p in report_order(poses)]
    assert ordered == [(v, p) for v in (100.0, 10.0) for p in ("P1", "P2", "P3", "P4", "P5", "P10")]
    assert sorted(["P1/x+", "P1", "P2"], key=natural_key) == ["P1", "P1/x+", "P2"]


def test_docstring_examples():
    from doctests import run_doctests

    import bench.metrology.formatting as module

    result = run_doctests(module)
    assert result.failed == 0 and result.attempted >= 3
