"""The deviations tables of the delta thesis's positioning test read by the laser grid (§8.4.2) and of ISO 9283
7.4/7.5 (position stabilisation time and overshoot from streamed arrivals); rows as in
:mod:`bench.reports.deviations`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any

from bench.metrology.documents import (
    GRID_RESOLUTION_MM,
    ISO9283_STABILISATION_BANDS_MM,
    LASERGRID_GUI_PLACEMENT,
    POSITIONING_POSES,
    POSITIONING_READINGS,
)
from bench.reports.deviations import (
    ISO_VELOCITIES_PCT,
    Deviation,
    _conditioning,
    _floats,
    _fmt,
    _load,
    _planned_count,
    _poses,
    _row,
    _unknown,
    complete,
)

__all__ = [
    "BAND_MIN_COUNTS",
    "ISO_BANDS_MM",
    "STABILISATION_CYCLES",
    "grid_positioning_deviations",
    "stabilisation_deviations",
]

# ---- the delta thesis's positioning test read by the laser grid (§8.4.2) and ISO 9283 7.4/7.5 (streamed arrivals) ----

#: ISO 9283 Table 5 [N]: cycles for position stabilisation time and overshoot; A.4 [N]: the comparison bands.
STABILISATION_CYCLES = 3
ISO_BANDS_MM = ISO9283_STABILISATION_BANDS_MM
#: A band narrower than this many instrument counts measures the sensor, not the robot (docs/campaigns.md).
BAND_MIN_COUNTS = 3


def grid_positioning_deviations(
    *,
    config: Mapping[str, Any],
    settings: Mapping[str, Any],
    poses: Sequence[Any],
    allow_unknown: bool = False,
    thesis: bool = True,
) -> list[Deviation]:
    """Departures of a ``delta_positioning`` run from the delta thesis's positioning test (§8.4.2) and from ISO 9283
    (7.2 pose characteristics, 6.6-6.10 conditions), computed from the stored configuration and settings and from
    ``poses``, the run's :class:`bench.metrology.partial_pose.GridPoseResult` (readings, axes measured, screens).
    ``thesis`` False: an ISO pose protocol read by the laser grid (no thesis rows; the protocol's own poses)."""
    rows = _grid_rows(config, settings, poses, thesis)
    if not thesis:
        rows = [row for row in rows if not row.clause.startswith("thesis")]
    return complete(rows, allow_unknown)


def _grid_rows(
    config: Mapping[str, Any], settings: Mapping[str, Any], poses: Sequence[Any], thesis: bool
) -> list[Deviation]:
    """The rows of :func:`grid_positioning_deviations`."""
    rows = []
    n_min = min(p.statistics.n_readings for p in poses)
    total = sum(p.statistics.n_readings for p in poses)
    requirement = ", ".join(f"({_fmt(target)})" for target in POSITIONING_POSES.values()) + " mm (thesis: cm)"
    if "poses" not in config:
        rows.append(_unknown("thesis §8.4.2", "thesis poses", requirement, "config.poses"))
    else:
        stored = {label: tuple(float(v) for v in target) for label, target in (config["poses"] or {}).items()}
        done = "; ".join(f"{label} ({_fmt(target)})" for label, target in stored.items()) + " mm"
        rows.append(
            _row(
                "thesis §8.4.2",
                "thesis poses",
                requirement,
                done,
                stored == POSITIONING_POSES,
                "not comparable pose by pose with the thesis (Appendix D1)",
            )
        )
    rows.append(
        _planned_count(
            "thesis §8.4.2",
            "readings",
            f"{POSITIONING_READINGS} readings per pose (thesis)",
            config,
            "cycles",
            measured=n_min,
            required=POSITIONING_READINGS,
            counted="stored",
            where="any pose",
            effect="wider scatter of every per-pose figure",
        )
    )
    instrument = settings.get("instrument") or {}
    requirement = "the screens' paper printout read by eye to the nearest mm (thesis)"
    if not instrument:
        rows.append(_unknown("thesis §8.4.2", "instrument", requirement, "settings.instrument"))
        rows.append(
            _unknown(
                "reference §6.5",
                "screen placement",
                "screen placement measured on the rig by the software calibration",
                "settings.instrument",
            )
        )
    else:
        window = (instrument.get("decoder") or {}).get("spot_half_width_mm")
        rows.append(
            _row(
                "thesis §8.4.2",
                "instrument",
                requirement,
                f"{instrument.get('instrument', 'laser grid')}: a reading is a {GRID_RESOLUTION_MM:g} mm "
                f"lattice point within ±r of the true position (r = "
                f"{'not stored' if window is None else f'{window:g} mm'}, decoder setting), or no reading",
                False,
                f"readings quantised to {GRID_RESOLUTION_MM:g} mm with ±r; figures not comparable "
                "reading by reading with the thesis's",
            )
        )
        placement = instrument.get("calibration_id")
        measured = placement is not None and placement != LASERGRID_GUI_PLACEMENT
        rows.append(
            _row(
                "reference §6.5",
                "screen placement",
                "screen placement measured on the rig by the software calibration (delta4-lasergrid.md §6.5)",
                f"calibration {placement or 'not stated'}"
                + ("" if measured else " (the legacy GUI drawing, not measured)"),
                measured,
                "which poses the grid can see at all depends on the placement: with the default "
                "one the thesis poses sit between four sensors of both screens (docs/campaigns.md)",
            )
        )
    counts = [sum(p.statistics.axes[k].n for p in poses) for k in range(3)]
    rows.append(
        _row(
            "ISO 9283 7.2",
            "partial readings",
            "every cycle gives the attained position x, y, z [U]",
            f"axes of a screen that did not decode are absent, never filled: x in {counts[0]}, y in "
            f"{counts[1]}, z in {counts[2]} of {total} readings",
            min(counts) == total,
            "each axis summarised over its own readings (its own n); an axis without readings has no figure",
        )
    )
    valid = {
        screen: (sum(p.valid[screen].k for p in poses), sum(p.valid[screen].n for p in poses))
        for screen in ("horizontal", "vertical")
    }
    rows.append(
        _row(
            "ISO 9283 7.2",
            "detection",
            "figures over every cycle, a random sample of the pose's scatter [U]",
            "every capture stored; screens valid in "
            + ", ".join(f"{screen} {k}/{n}" for screen, (k, n) in valid.items()),
            all(k == n for k, n in valid.values()),
            "figures are conditional on detection: the grid sees a pose only within r of its lattice points, "
            "so the detected readings are not a random sample of the pose's scatter",
        )
    )
    complete_readings = ", ".join(f"{p.pose} {p.statistics.n_complete}/{p.statistics.n_readings}" for p in poses)
    rows.append(
        _row(
            "ISO 9283 7.2.1/7.2.2",
            "spatial AP/RP",
            "AP_P and RP_l over every cycle's attained pose [U]",
            f"over the complete readings only (all three axes): {complete_readings}",
            all(p.statistics.n_complete == p.statistics.n_readings for p in poses),
            "no AP with 0 and no RP with fewer than 2 complete readings; those given rest on fewer cycles",
        )
    )
    rows.append(
        _row(
            "ISO 9283 6.9",
            "cycles",
            "30 cycles per pose (Table 5)",
            f"{n_min} (fewest at any pose)",
            n_min >= 30,
            "wider confidence interval on AP and RP",
        )
    )
    rows.append(
        _row(
            "ISO 9283 6.8",
            "poses",
            "P1-P5 in the largest cube of the most-used workspace (6.8) [U]",
            "the thesis's three poses" if thesis else f"the protocol's {len(poses)} poses",
            False,
            "not comparable with ISO cube results of other robots",
        )
    )
    velocity = (settings.get("robot") or {}).get("velocity", "not stated")
    rows.append(
        _row(
            "ISO 9283 6.7",
            "velocity",
            f"{_fmt(ISO_VELOCITIES_PCT)} % of rated velocity [U]",
            f"{velocity}",
            False,
            "one, undeclared velocity; velocity-dependent errors not covered",
        )
    )
    rows.append(
        _row(
            "ISO 9283 6.6",
            "load",
            "100 % rated load (6.6)",
            "no load recorded (the protocol has none)"
            if thesis
            else f"loads {config.get('loads_kg', 'not stated')} kg",
            False,
            "results describe the unloaded end effector only",
        )
    )
    rows.append(
        _row(
            "ISO 9283 6.10",
            "settling",
            "measure once the controller signals the attained pose and it has settled [U]",
            f"after the controller's settled signal (z) and a dwell of {config.get('settle_s', '—')} s; the "
            "first sensor report begun after the capture was asked",
            True,
            "",
        )
    )
    rows.append(
        _row(
            "ISO 9283 7.2",
            "dimensionality",
            "6-D poses: position x, y, z and orientation a, b, c [U]",
            "position only, each axis where a screen measured it",
            False,
            "no orientation AP/RP",
        )
    )
    rows.append(_conditioning(config, "ISO 9283 6.2/6.3"))
    return rows


def stabilisation_deviations(
    *,
    config: Mapping[str, Any],
    settings: Mapping[str, Any],
    cycles_measured: int,
    bands_mm: Sequence[float],
    hysteresis_mm: float,
    hysteresis_source: str,
    count_mm: float | None,
    window_problems: Sequence[str],
    allow_unknown: bool = False,
) -> list[Deviation]:
    """Departures of an ``iso9283_stabilisation`` run from ISO 9283 7.4 and 7.5 (iso9283.md §4.2, §6.6-6.7):
    cycles, poses, velocity, load, the bands and the hysteresis chosen at analysis, the streamed windows
    (``window_problems``: arrivals whose window missed the entry into the band or the settling) and the
    instrument (``count_mm``: one count of it, None when not stored)."""
    robot = settings.get("robot") or {}
    rows = []
    rows.append(
        _planned_count(
            "ISO 9283 6.9",
            "cycles",
            f"{STABILISATION_CYCLES} cycles per pose (Table 5)",
            config,
            "cycles",
            measured=cycles_measured,
            required=STABILISATION_CYCLES,
            counted="stored",
            where="any pose",
            effect="mean t_s and OV over fewer arrivals than the standard's",
        )
    )
    rows.append(replace(_poses(config)[0], clause="ISO 9283 6.8"))
    requirement = "100 % of rated velocity (iso9283.md §4.2) [U]"
    if "velocities_pct" not in config:
        rows.append(_unknown("ISO 9283 6.7", "velocity", requirement, "config.velocities_pct"))
    else:
        velocities = _floats(config["velocities_pct"])
        rated_mm_s = robot.get("rated_velocity_mm_s")
        rated = (
            f"rated {float(rated_mm_s):g} mm/s"
            if rated_mm_s is not None
            else f"rated = firmware maximum {robot['rated_speed_steps_s']} steps/s, no rated mm/s"
            if "rated_speed_steps_s" in robot
            else "no rated velocity stated"
        )
        rows.append(
            _row(
                "ISO 9283 6.7",
                "velocity",
                requirement,
                f"{_fmt(velocities)} % ({rated})",
                velocities == [100.0] and rated_mm_s is not None,
                "the arrival speed, which drives the overshoot, is not a declared rated speed: the legs run "
                "at the rated step rate, so the end effector arrives faster in some directions than others",
            )
        )
    rows.append(replace(_load(config, robot), clause="ISO 9283 6.6"))
    rows.append(
        _row(
            "ISO 9283 7.4",
            "limit band",
            f"B = RP or the manufacturer's value; comparison bands {_fmt(ISO_BANDS_MM)} mm (A.4) [N]",
            f"{_fmt(bands_mm)} mm, chosen at analysis (the run stores the whole arrival)",
            all(band in ISO_BANDS_MM for band in bands_mm),
            "not comparable with comparison-test results",
        )
    )
    rows.append(
        _row(
            "ISO 9283 7.4/7.5",
            "hysteresis",
            "t_2: d(t) <= B from then on; OV counted when max d > B (as written) [U]",
            "h = 0, the definition as written"
            if hysteresis_mm == 0
            else f"h = {hysteresis_mm:g} mm ({hysteresis_source}): excursions up to B + h are not counted",
            hysteresis_mm == 0,
            "t_s and OV leave out excursions up to h beyond B (band-edge flicker of the quantised "
            "instrument, which the definition as written reads as an overshoot of about B)",
        )
    )
    requirement = (
        "the series covers the approach into the band and the ringing until settled; p_att the settled "
        "attained position (iso9283.md §6.6)"
    )
    if "lead_s" not in config or "hold_s" not in config:
        rows.append(_unknown("ISO 9283 7.4", "windows", requirement, "config.lead_s, config.hold_s"))
    else:
        done = (
            f"{float(config['lead_s']):g} s before the move-done signal to {float(config['hold_s']):g} s after "
            "it, no dwell; p_att = the last sample of each arrival"
        )
        rows.append(
            _row(
                "ISO 9283 7.4",
                "windows",
                requirement,
                done + ("" if not window_problems else "; " + "; ".join(window_problems)),
                not window_problems,
                "t_1 not observed (the window opened inside the band) or no t_2 (the "
                "arrival had not settled when the window closed)",
            )
        )
    instrument = settings.get("instrument") or {}
    requirement = "a time-series instrument sampled much faster than the settling, resolving the band (iso9283.md §6.6)"
    if not instrument:
        rows.append(_unknown("ISO 9283 7.4", "instrument", requirement, "settings.instrument"))
    else:
        rate = instrument.get("report_rate_hz")
        name = instrument.get("instrument", instrument.get("name", "instrument"))
        resolves = count_mm is not None and min(bands_mm) >= BAND_MIN_COUNTS * count_mm
        done = (
            f"{name}; {'report rate not stated' if rate is None else f'reports at up to {rate:g} Hz'} (only on "
            f"motion; zero-order hold between reports); one count "
            f"{'not stored' if count_mm is None else f'= {count_mm:.4g} mm'}"
        )
        if count_mm is not None:
            done += f", the narrowest band {min(bands_mm) / count_mm:.1f} counts"
        rows.append(
            _row(
                "ISO 9283 7.4",
                "instrument",
                requirement,
                done,
                resolves and rate is not None,
                f"a band narrower than about {BAND_MIN_COUNTS} counts measures the sensor, not the robot",
            )
        )
    rows.append(_conditioning(config, "ISO 9283 6.2/6.3"))
    return complete(rows, allow_unknown)
