"""The deviations table is computed from the stored configuration (iso9283.md §11.2) and refuses unknown rows."""

from __future__ import annotations

import pytest
from reports_runs import SETTINGS, pose_config

from bench.errors import InsufficientData
from bench.reports import iso_deviations

ISO_SETTINGS = {
    "robot": {"rated_load_kg": 2.0, "rated_velocity_mm_s": 50.0},
    "instrument": {"instrument": "laser tracker", "u_mm": 0.005},
}
ISO_CONFIG = pose_config(cycles=30, velocities_pct=[100.0, 50.0, 10.0], loads_kg=[2.0], warmup_s=1800.0, ambient_c=20.5)
SIX_D = ("x_mm", "y_mm", "z_mm", "a_deg", "b_deg", "c_deg")


def _table(
    config=ISO_CONFIG, settings=ISO_SETTINGS, measured=SIX_D, cycles=30, sigma=0.005, rp=0.2, floor=0.018, **kwargs
):
    rows = iso_deviations(
        protocol=config["protocol"],
        config=config,
        settings=settings,
        measured_columns=measured,
        cycles_measured=cycles,
        instrument_sigma_mm=sigma,
        smallest_rp_mm=rp,
        rp_floor_mm=floor,
        **kwargs,
    )
    return {r.topic: r for r in rows}


def test_every_topic_of_the_issue_is_listed():
    assert {"cycles", "poses", "plane", "load", "velocity", "sensor", "dimensionality"} <= set(_table())


def test_a_run_under_iso_conditions_has_no_deviation_but_the_settling_rule():
    statuses = {topic: row.status for topic, row in _table().items()}
    assert statuses.pop("settling") == "deviates"  # a fixed dwell is never the controller's attained-pose signal
    assert set(statuses.values()) == {"conforms"}


def test_the_dissertation_style_run_deviates_everywhere_it_should():
    config = pose_config(
        cycles=10,
        poses={"1-1": [100.0, -110.0, 300.0], "1-2": [110.0, -100.0, 300.0]},
        velocities_pct=[100.0],
        loads_kg=[0.0],
    )
    rows = _table(config, SETTINGS, ("x_mm", "y_mm"), cycles=10, sigma=0.355, rp=1.56, floor=1.14)
    for topic in ("cycles", "poses", "plane", "load", "velocity", "sensor", "dimensionality", "approach"):
        assert rows[topic].status == "deviates", topic
        assert rows[topic].effect
    assert rows["cycles"].done == "10 planned"
    assert rows["poses"].done.startswith("explicit pose set (1-1, 1-2)")
    assert "no rated load" in rows["load"].done
    assert "73 % of the smallest RP" in rows["sensor"].done  # 1.14 / 1.56, the OCM example of iso9283.md §8.4
    assert "fewer than 3 dimensions" in rows["dimensionality"].effect


def test_cycles_measured_below_planned_is_shown():
    row = _table(cycles=12)["cycles"]
    assert (row.status, row.done) == ("deviates", "30 planned, 12 measured (fewest at any pose)")


def test_velocity_needs_all_three_and_a_rating_in_mm_s():
    assert _table(pose_config(**{**ISO_CONFIG, "velocities_pct": [100.0]}))["velocity"].status == "deviates"
    unrated = {**ISO_SETTINGS, "robot": {"rated_load_kg": 2.0, "rated_speed_steps_s": 200}}
    row = _table(settings=unrated)["velocity"]
    assert row.status == "deviates" and "200 steps/s, no rated mm/s" in row.done


def test_load_must_include_the_rated_load():
    assert _table(pose_config(**{**ISO_CONFIG, "loads_kg": [0.2]}))["load"].status == "deviates"


def test_sensor_floor_above_a_quarter_of_rp_deviates():
    assert _table(floor=0.05, rp=0.2)["sensor"].status == "conforms"
    assert _table(floor=0.051, rp=0.2)["sensor"].status == "deviates"


def test_position_only_measurement_is_a_dimensionality_deviation():
    row = _table(measured=("x_mm", "y_mm", "z_mm"))["dimensionality"]
    assert (row.status, row.effect) == ("deviates", "orientation AP/RP not reported")


@pytest.mark.parametrize(
    ("drop", "clause"),
    [
        ("cycles", "clause 6.9 cycles"),
        ("loads_kg", "clause 6.6 load"),
        ("velocities_pct", "clause 6.7 velocity"),
        ("settle_s", "clause 6.10 settling"),
    ],
)
def test_unknown_rows_refuse_the_report_naming_the_clause(drop, clause):
    config = {k: v for k, v in ISO_CONFIG.items() if k != drop}
    with pytest.raises(InsufficientData, match=f"refusing to report.*{clause}: not stored: config.{drop}"):
        _table(config)
    assert _table(config, allow_unknown=True)[clause.split()[-1]].status == "unknown"


def test_no_instrument_description_refuses_the_report():
    with pytest.raises(InsufficientData, match="clause 6.5 sensor: not stored: settings.instrument"):
        _table(settings={"robot": ISO_SETTINGS["robot"]}, sigma=None, floor=None)
