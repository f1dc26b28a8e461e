"""The deviations tables of the documents' bench tests: the actuator test (000 §8.4), the payload ladder (000 §8.7)
and the laser grid's hit test (§8.4.3); rows as in :mod:`bench.reports.deviations` (conforms, deviates, unknown).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from typing import Any

from bench.metrology.documents import (
    ACTUATOR_REPEATS,
    ACTUATOR_TRAVELS_MM,
    GRID_HEIGHTS_MM,
    GRID_HIT_ATTEMPTS,
    GRID_OFFSET_MM,
    GRID_SENSORS,
    LADDER_KG,
    LADDER_LIFT_MM,
)
from bench.metrology.formatting import format_uncertainty
from bench.reports.deviations import (
    Deviation,
    _conditioning,
    _floats,
    _fmt,
    _load,
    _planned_count,
    _row,
    _unknown,
    complete,
)

__all__ = ["LADDER_MIN_REPEATS", "actuator_deviations", "grid_hit_deviations", "ladder_deviations"]

# ---- the documents' bench tests: the actuator test (000 §8.4), the payload ladder (000 §8.7), grid hits (§8.4.3) ----

# The documents' own figures (travels, loads, lift, heights, attempts, ...) are bench.metrology.documents'.
#: iso9283.md §12.3 [P]: lifts per rung of the payload ladder.
LADDER_MIN_REPEATS = 3


def _instrument_row(clause: str, reader: str | None, sigma_mm: float | None, stated: bool, note: str = "") -> Deviation:
    """The uncertainty of manual length readings (calliper, depth gauge): stated, or the resolution only."""
    requirement = "gauge uncertainty stated: data-sheet MPE or calibration certificate (sensors.md §6.1) [U]"
    if reader is None:
        return _unknown(clause, "instrument", requirement, "settings.instrument")
    if stated:
        return _row(
            clause, "instrument", requirement, f"{reader}; u = {format_uncertainty(sigma_mm)} mm per reading", True, ""
        )
    if sigma_mm is None:
        return _row(
            clause,
            "instrument",
            requirement,
            f"{reader}; no uncertainty stated or derivable{note}",
            False,
            "U covers the scatter of the readings only",
        )
    return _row(
        clause,
        "instrument",
        requirement,
        f"{reader}; u = {format_uncertainty(sigma_mm)} mm from the reading resolution only (no MPE or calibration stored){note}",
        False,
        "U covers the scatter and the resolution, not the gauge's own error (about ±0.02 mm for a 150 mm calliper [U])",
    )


def actuator_deviations(
    *,
    config: Mapping[str, Any],
    settings: Mapping[str, Any],
    repeats_measured: int,
    instrument_sigma_mm: float | None,
    uncertainty_stated: bool = False,
    allow_unknown: bool = False,
) -> list[Deviation]:
    """Departures of an ``actuator_accuracy`` run from the dissertation's actuator test (000 §8.4) and from
    ISO 230-2 (iso9283.md §7.1, from memory [U]), whose unidirectional figures the report adds."""
    rows = []
    requirement = "actuators free-standing under a beam, revolute joints removed (000 §8.4)"
    if "fixture" not in config:
        rows.append(_unknown("000 §8.4", "fixture", requirement, "config.fixture"))
    else:
        rows.append(
            _row(
                "000 §8.4",
                "fixture",
                requirement,
                f"fixture = {config['fixture']}: one actuator moves, the others hold; unloaded",
                config["fixture"] == "actuator-bench",
                "single-axis figures do not apply",
            )
        )
    requirement = f"commanded travels {_fmt(ACTUATOR_TRAVELS_MM)} mm (000 §8.4)"
    travels = _floats(config.get("distances_mm") or [])
    if not travels:
        rows.append(_unknown("000 §8.4", "travels", requirement, "config.distances_mm"))
        rows.append(
            _unknown("ISO 230-2", "targets", "at least 5 irregularly spaced targets [U]", "config.distances_mm")
        )
    else:
        rows.append(
            _row(
                "000 §8.4",
                "travels",
                requirement,
                f"{_fmt(travels)} mm",
                sorted(travels) == sorted(ACTUATOR_TRAVELS_MM),
                "not comparable target by target with 000 Tables A.1-A.7",
            )
        )
        steps = {round(b - a, 6) for a, b in zip(sorted(travels), sorted(travels)[1:])}
        regular = len(steps) <= 1
        rows.append(
            _row(
                "ISO 230-2",
                "targets",
                "at least 5 targets, irregularly spaced so that periodic errors are sampled [U]",
                f"{len(travels)} targets" + (", evenly spaced" if regular and len(travels) > 1 else ""),
                len(travels) >= 5 and not regular,
                "periodic (lead-screw) errors sampled at fixed phases only"
                if regular
                else "systematic error E and accuracy A from too few targets",
            )
        )
    both_ways = config.get("approach") == "bidirectional"
    if both_ways:
        rows.append(
            _planned_count(
                "ISO 230-2",
                "cycles",
                "5 approaches per target and direction [U]",
                config,
                "cycles",
                measured=repeats_measured,
                required=5,
                counted="complete",
                where="any actuator",
                effect="wider uncertainty of s↑, s↓ and so of R and A",
            )
        )
        rows.append(
            _row(
                "000 §8.4",
                "repeats",
                f"{ACTUATOR_REPEATS} repeats per travel (000 §8.4)",
                f"{repeats_measured} approaches from below per travel (the ISO 230-2 cycles)",
                repeats_measured >= ACTUATOR_REPEATS,
                "wider uncertainty of σ̄, and so of Groover's repeatability and accuracy",
            )
        )
    else:
        rows.append(
            _planned_count(
                "000 §8.4",
                "repeats",
                f"{ACTUATOR_REPEATS} repeats per travel (000 §8.4; ISO 230-2: 5 per direction [U])",
                config,
                "repeats",
                measured=repeats_measured,
                required=ACTUATOR_REPEATS,
                counted="complete",
                where="any actuator",
                effect="wider uncertainty of σ̄, and so of the repeatability and accuracy",
            )
        )
    rows.append(
        _row(
            "ISO 230-2",
            "direction",
            "approaches in both directions with an overrun at each reversal [U]",
            f"bidirectional linear cycles, overrun {float(config.get('overrun_mm', 0)):g} mm at each reversal"
            if both_ways
            else "unidirectional: every reading approached from below, from the start stroke",
            both_ways,
            "reversal B (backlash) and the bidirectional R, E, A not measured; ↑ figures only",
        )
    )
    requirement = "initial and final depth read at every travel (000 §8.4, sensors.md §6.2)"
    if "start_mm" not in config:
        rows.append(_unknown("000 §8.4", "zeroing", requirement, "config.start_mm"))
    else:
        rows.append(
            _row(
                "000 §8.4",
                "zeroing",
                requirement,
                (
                    f"gauge zeroed once per actuator at {float(config['start_mm']):g} mm stroke; the targets "
                    "are read in passes up and down, never back at the start"
                    if both_ways
                    else f"gauge zeroed once per actuator and travel at {float(config['start_mm']):g} mm stroke; "
                    "each repeat returns to the start and is read at the end only"
                ),
                False,
                "the error of returning to the start enters every reading instead of cancelling",
            )
        )
    instrument = settings.get("instrument") or {}
    reader = instrument.get("instrument", instrument.get("name", "instrument")) if instrument else None
    rows.append(_instrument_row("000 §8.4", reader, instrument_sigma_mm, uncertainty_stated))
    rows.append(_conditioning(config, "ISO 230-2"))
    return complete(rows, allow_unknown)


def _ladder_shape(loads: list[float]) -> tuple[bool, bool]:
    """(bracketed by unloaded references, ascending then descending)."""
    bracketed = len(loads) > 2 and loads[0] == 0 and loads[-1] == 0
    peak = loads.index(max(loads))
    hysteresis = (
        0 < peak < len(loads) - 1
        and loads[: peak + 1] == sorted(loads[: peak + 1])
        and loads[peak:] == sorted(loads[peak:], reverse=True)
    )
    return bracketed, hysteresis


def ladder_deviations(
    *,
    config: Mapping[str, Any],
    settings: Mapping[str, Any],
    repeats_measured: int,
    instrument_sigma_mm: float | None,
    reference_load_kg: float | None,
    g_m_s2: float,
    reader: str,
    allow_unknown: bool = False,
) -> list[Deviation]:
    """Departures of a ``payload_ladder`` run from the dissertation's ladder (000 §8.7, Table A.14), the project
    protocol (iso9283.md §12.3) and ISO 9283 6.6 (rated load)."""
    rows = []
    requirement = f"the {len(LADDER_KG)} loads of Table A.14, {LADDER_KG[0]:g}-{LADDER_KG[-1]:g} kg (000 §8.7)"
    loads = _floats(config.get("loads_kg") or [])
    if not loads:
        rows += [
            _unknown("000 §8.7", "ladder", requirement, "config.loads_kg"),
            _unknown(
                "project §12.3", "reference runs", "unloaded reference runs before and after [P]", "config.loads_kg"
            ),
            _unknown("project §12.3", "hysteresis", "ascending, then descending [P]", "config.loads_kg"),
        ]
    else:
        rows.append(
            _row(
                "000 §8.7",
                "ladder",
                requirement,
                f"{len(loads)} loads: {_fmt(loads)} kg",
                loads == _floats(LADDER_KG),
                "not comparable load by load with 000 Tables A.14 and 8-5",
            )
        )
        bracketed, hysteresis = _ladder_shape(loads)
        rows.append(
            _row(
                "project §12.3",
                "reference runs",
                "unloaded reference runs before and after the ladder [P]",
                "ladder starts and ends at 0 kg" if bracketed else "no unloaded run before and after",
                bracketed,
                "permanent set or damage during the ladder not detectable",
            )
        )
        rows.append(
            _row(
                "project §12.3",
                "hysteresis",
                "ladder run ascending, then descending [P]",
                "ascending then descending" if hysteresis else "one direction only",
                hysteresis,
                "hysteresis of the structure under load not exposed",
            )
        )
    requirement = f"pure vertical lift of {LADDER_LIFT_MM:g} mm, the same command pose at every load (000 §8.7)"
    if "lift_mm" not in config:
        rows.append(_unknown("000 §8.7", "lift", requirement, "config.lift_mm"))
    else:
        start = _floats(config.get("start_mm") or [])
        rows.append(
            _row(
                "000 §8.7",
                "lift",
                requirement,
                f"{float(config['lift_mm']):g} mm up from ({_fmt(start)}) mm",
                float(config["lift_mm"]) == LADDER_LIFT_MM,
                "leg lengths not comparable with 000's",
            )
        )
    rows.append(
        _planned_count(
            "project §12.3",
            "repeats",
            f"at least {LADDER_MIN_REPEATS} lifts per load (§12.3 [P]; 000: 1)",
            config,
            "repeats",
            measured=repeats_measured,
            required=LADDER_MIN_REPEATS,
            counted="complete",
            where="any load",
            effect="no scatter per load: a change of e_i(m) with load cannot be told from reading scatter",
        )
    )
    rows.append(
        _row(
            "project §12.1",
            "measurand",
            "leg lengths by calliper (000 mode) and/or end-effector displacement at the same command pose [P]",
            "six calliper leg lengths per lift against the IK lengths of the commanded lifted pose; PE(m) "
            "derived from them by forward kinematics, no end-effector sensor",
            True,
            "",
        )
    )
    rows.append(
        _row(
            "project §12.1",
            "reference load",
            "reference load m₀ and g stated [P]",
            "no loads"
            if reference_load_kg is None
            else f"m₀ = {reference_load_kg:g} kg (lowest load), g = {g_m_s2:g} m/s²",
            reference_load_kg is not None,
            "PE(m) and k undefined",
        )
    )
    rows.append(replace(_load(config, settings.get("robot") or {}), clause="ISO 9283 6.6"))
    rig = (settings.get("instrument") or {}).get("instrument")
    rows.append(
        _instrument_row(
            "000 §8.7",
            reader,
            instrument_sigma_mm,
            False,
            f"; the stored instrument settings describe the rig's {rig}, not the calliper"
            if rig
            else "; no calliper described in the stored settings",
        )
    )
    rows.append(_conditioning(config, "ISO 9283 6.2/6.3"))
    return complete(rows, allow_unknown)


def grid_hit_deviations(
    *, config: Mapping[str, Any], settings: Mapping[str, Any], attempts_measured: int, allow_unknown: bool = False
) -> list[Deviation]:
    """Departures of a ``lasergrid_hits`` run from the delta thesis's hit-repeatability test (§8.4.3, Appendix
    D2) and from the choices delta4-lasergrid.md §7.3 makes where the thesis is silent."""
    rows = []
    requirement = f"{GRID_SENSORS} sensors (thesis; which ones not stated), a 4 x 4 spread [reference choice]"
    if "spread" not in config:
        rows.append(_unknown("thesis §8.4.3", "sensors", requirement, "config.spread"))
    else:
        spread = int(config["spread"])
        rows.append(
            _row(
                "thesis §8.4.3",
                "sensors",
                requirement,
                f"{spread * spread} sensors in a {spread} x {spread} spread over the horizontal screen",
                spread * spread == GRID_SENSORS,
                "group rate over other sensors than the thesis's",
            )
        )
    rows.append(
        _planned_count(
            "thesis §8.4.3",
            "attempts",
            f"{GRID_HIT_ATTEMPTS} attempts per sensor and height (thesis)",
            config,
            "attempts",
            measured=attempts_measured,
            required=GRID_HIT_ATTEMPTS,
            counted="stored",
            where="any sensor and height",
            effect="wider interval on every rate; one miss moves a sensor's rate by more than 4 %",
        )
    )
    requirement = f"{_fmt(GRID_HEIGHTS_MM)} mm below the base (thesis: 14, 17, 20 cm)"
    if "heights_mm" not in config:
        rows.append(_unknown("thesis §8.4.3", "heights", requirement, "config.heights_mm"))
    else:
        heights = [-v for v in _floats(config["heights_mm"])]
        rows.append(
            _row(
                "thesis §8.4.3",
                "heights",
                requirement,
                f"{_fmt(heights)} mm below the base",
                sorted(heights) == sorted(GRID_HEIGHTS_MM),
                "rates not comparable height by height",
            )
        )
    requirement = (
        f"not stated (thesis); a re-approach from a random {_fmt(GRID_OFFSET_MM)} mm offset at every "
        "attempt [reference choice]"
    )
    if "offset_mm" not in config:
        rows.append(_unknown("reference §7.3", "approach", requirement, "config.offset_mm"))
    else:
        offset = _floats(config["offset_mm"])
        rows.append(
            _row(
                "reference §7.3",
                "approach",
                requirement,
                f"random re-approach from {offset[0]:g}-{offset[-1]:g} mm, seed {config.get('seed', 'not stored')}",
                offset == list(GRID_OFFSET_MM),
                "a different approach changes the positioning scatter tested",
            )
        )
    rows.append(
        _row(
            "reference §7.3",
            "hit",
            "not stated (thesis); log the expected sensor and any sensor [reference choice]",
            "rate = expected sensor reported; the any-sensor rate beside it",
            True,
            "",
        )
    )
    instrument = settings.get("instrument") or {}
    requirement = "the laser grid's calibration (sensor positions) stated"
    if not instrument:
        rows.append(_unknown("reference §7.3", "instrument", requirement, "settings.instrument"))
    else:
        calibration = instrument.get("calibration_id")
        rows.append(
            _row(
                "reference §7.3",
                "instrument",
                requirement,
                f"{instrument.get('instrument', 'laser grid')}; calibration {calibration or 'not stated'}",
                calibration is not None,
                "which sensor was commanded is not traceable",
            )
        )
    return complete(rows, allow_unknown)
