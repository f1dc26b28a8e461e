"""The deviations table: every departure of a stored run from the ISO 9283 test conditions, one row per clause.

Rows are computed from the run's stored configuration (the resolved protocol parameters), its rig settings and
the measured columns of its samples, never typed by hand (iso9283.md §11.2 [P]). The requirements are those of
iso9283.md §3-5 (clauses 6.2-6.10, Table 5 for the number of cycles); items tagged [U] there are paraphrased
from memory of the standard and say so in the requirement text.

A row has one of three statuses: ``conforms``, ``deviates`` or ``unknown`` (the stored run lacks what the row
needs). :func:`iso_deviations` raises :class:`~bench.errors.InsufficientData` when any row is unknown, naming the
clauses and the missing fields: the report refuses to print a deviations table with holes (§11.2 rule 1).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

from bench.errors import InsufficientData
from bench.metrology.documents import (
    ACTUATOR_REPEATS,
    ACTUATOR_TRAVELS_MM,
    GRID_HEIGHTS_MM,
    GRID_HIT_ATTEMPTS,
    GRID_OFFSET_MM,
    GRID_RESOLUTION_MM,
    GRID_SENSORS,
    ISO9283_CYCLES,
    ISO9283_POSE_ORDER,
    ISO9283_STABILISATION_BANDS_MM,
    ISO9283_VELOCITIES_PCT,
    LADDER_KG,
    LADDER_LIFT_MM,
    LASERGRID_GUI_PLACEMENT,
    POSITIONING_POSES,
    POSITIONING_READINGS,
)
from bench.metrology.formatting import format_uncertainty

__all__ = [
    "ACTUATOR_REPEATS",
    "ACTUATOR_TRAVELS_MM",
    "BAND_MIN_COUNTS",
    "CLAUSES_APPLIED",
    "GRID_HEIGHTS_MM",
    "GRID_HIT_ATTEMPTS",
    "GRID_OFFSET_MM",
    "ISO_BANDS_MM",
    "ISO_CYCLES",
    "ISO_VELOCITIES_PCT",
    "LADDER_LIFT_MM",
    "LADDER_MIN_REPEATS",
    "POSITIONING_READINGS",
    "STABILISATION_CYCLES",
    "Deviation",
    "actuator_deviations",
    "complete",
    "grid_hit_deviations",
    "grid_positioning_deviations",
    "iso_deviations",
    "ladder_deviations",
    "orientation_deviation",
    "stabilisation_deviations",
]

#: Cycles required per protocol (ISO 9283 Table 5 [N]: 30 for AP/RP, AD/RD and vAP).
ISO_CYCLES = {
    "iso9283_pose": ISO9283_CYCLES,
    "iso9283_distance": ISO9283_CYCLES,
    "iso9283_multidirectional": ISO9283_CYCLES,
}
#: Test velocities, % of rated (clause 6.7 [U]).
ISO_VELOCITIES_PCT = ISO9283_VELOCITIES_PCT
#: Clauses applied by each protocol (ISO 9283 clause numbers).
CLAUSES_APPLIED = {
    "iso9283_pose": ("7.2.1 pose accuracy AP", "7.2.2 pose repeatability RP"),
    "iso9283_distance": ("7.3 distance accuracy AD and repeatability RD",),
    "iso9283_multidirectional": ("7.2.3 multi-directional pose accuracy variation vAP",),
}
_ISO_ORDER = " -> ".join(ISO9283_POSE_ORDER) + ", unidirectional"


@dataclass(frozen=True)
class Deviation:
    """One row of the deviations table."""

    clause: str  #: ISO 9283 clause, e.g. "6.9"
    topic: str  #: cycles, poses, plane, load, velocity, sensor, dimensionality, ...
    requirement: str  #: what ISO 9283 asks for (tagged [U] where unverified)
    done: str  #: what this run did, from its stored configuration
    status: str  #: "conforms", "deviates" or "unknown"
    effect: str = ""  #: expected effect on the results ("" when it conforms)


def _fmt(values: Sequence[float]) -> str:
    return ", ".join(f"{v:g}" for v in values)


def _row(clause, topic, requirement, done, conforms, effect) -> Deviation:
    return Deviation(
        clause, topic, requirement, done, "conforms" if conforms else "deviates", "" if conforms else effect
    )


def _unknown(clause: str, topic: str, requirement: str, missing: str) -> Deviation:
    return Deviation(clause, topic, requirement, f"not stored: {missing}", "unknown")


def _planned_count(
    clause: str,
    topic: str,
    requirement: str,
    config: Mapping[str, Any],
    key: str,
    *,
    measured: int,
    required: int,
    counted: str,
    where: str,
    effect: str,
) -> Deviation:
    """The row of a repeated measurement (cycles, repeats, attempts): the count planned in ``config[key]`` and, when
    it differs, the ``measured`` one (the fewest at any ``where``, ``counted`` e.g. "stored"); it conforms when both
    reach ``required``, and is unknown when the configuration has no ``key``."""
    if key not in config:
        return _unknown(clause, topic, requirement, f"config.{key}")
    planned = int(config[key])
    done = f"{planned} planned" + ("" if measured == planned else f", {measured} {counted} (fewest at {where})")
    return _row(clause, topic, requirement, done, min(planned, measured) >= required, effect)


def _cycles(config: Mapping[str, Any], protocol: str, cycles_measured: int) -> Deviation:
    required = ISO_CYCLES.get(protocol, ISO9283_CYCLES)
    return _planned_count(
        "6.9",
        "cycles",
        f"{required} cycles per pose (Table 5)",
        config,
        "cycles",
        measured=cycles_measured,
        required=required,
        counted="measured",
        where="any pose",
        effect="wider confidence interval on RP and AP; RP's 3 S_l term less stable",
    )


def _poses(config: Mapping[str, Any]) -> list[Deviation]:
    requirement = "P1-P5 in the largest cube fitting the most-used workspace region (6.8) [U]"
    plane_requirement = "P2-P5 on one diagonal plane of the cube, 10 % of the diagonal from the corners [U]"
    if "poses" not in config:
        return [
            _unknown("6.8", "poses", requirement, "config.poses"),
            _unknown("6.8", "plane", plane_requirement, "config.poses"),
        ]
    if config["poses"]:
        labels = ", ".join(config["poses"])
        return [
            _row(
                "6.8",
                "poses",
                requirement,
                f"explicit pose set ({labels}) instead of the cube",
                False,
                "not comparable with ISO cube results of other robots",
            ),
            _row(
                "6.8",
                "plane",
                plane_requirement,
                "no cube diagonal plane (explicit poses)",
                False,
                "poses do not span the cube's diagonal plane",
            ),
        ]
    side = config.get("cube_side_mm")
    if side is None or "plane" not in config:
        return [
            _unknown("6.8", "poses", requirement, "config.cube_side_mm"),
            _unknown("6.8", "plane", plane_requirement, "config.plane"),
        ]
    centre = config.get("cube_centre_mm", [])
    return [
        _row(
            "6.8",
            "poses",
            requirement,
            f"cube of edge {float(side):g} mm centred at ({_fmt(centre)}) mm, the largest passing the pre-flight",
            True,
            "",
        ),
        _row("6.8", "plane", plane_requirement, f"diagonal plane {config['plane']} at 0.4 L from P1", True, ""),
    ]


def _load(config: Mapping[str, Any], robot_settings: Mapping[str, Any]) -> Deviation:
    requirement = "100 % rated load (6.6), optionally repeated at 10 %"
    if "loads_kg" not in config:
        return _unknown("6.6", "load", requirement, "config.loads_kg")
    loads = [float(v) for v in config["loads_kg"]]
    rated = robot_settings.get("rated_load_kg")
    if rated is None:
        return _row(
            "6.6",
            "load",
            requirement,
            f"loads {_fmt(loads)} kg; the robot has no rated load",
            False,
            "AP/RP optimistic for loaded use; results hold for the stated loads only",
        )
    conforms = float(rated) in loads
    return _row(
        "6.6",
        "load",
        requirement,
        f"loads {_fmt(loads)} kg (rated {float(rated):g} kg)",
        conforms,
        "results do not describe the rated-load condition",
    )


def _velocity(config: Mapping[str, Any], robot_settings: Mapping[str, Any], protocol: str) -> Deviation:
    requirement = f"{_fmt(ISO_VELOCITIES_PCT)} % of rated velocity (6.7) [U]"
    if "velocities_pct" not in config:
        return _unknown("6.7", "velocity", requirement, "config.velocities_pct")
    velocities = [float(v) for v in config["velocities_pct"]]
    rated_mm_s = robot_settings.get("rated_velocity_mm_s")
    rated = (
        f"rated {float(rated_mm_s):g} mm/s"
        if rated_mm_s is not None
        else f"rated = firmware maximum {robot_settings['rated_speed_steps_s']} steps/s, no rated mm/s"
        if "rated_speed_steps_s" in robot_settings
        else "no rated velocity stated"
    )
    conforms = sorted(velocities) == sorted(ISO_VELOCITIES_PCT) and rated_mm_s is not None
    return _row(
        "6.7",
        "velocity",
        requirement,
        f"{_fmt(velocities)} % ({rated})",
        conforms,
        "velocity-dependent errors only partly covered; % of an undeclared rating is not comparable",
    )


def _sensor(
    instrument: Mapping[str, Any], sigma_mm: float | None, smallest_rp_mm: float | None, floor_mm: float | None
) -> Deviation:
    requirement = "instrument uncertainty well below the characteristic measured (6.5) [U]"
    if not instrument or sigma_mm is None:
        return _unknown("6.5", "sensor", requirement, "settings.instrument (description and uncertainty)")
    name = instrument.get("instrument", instrument.get("name", "instrument"))
    done = f"{name}; u = {format_uncertainty(sigma_mm)} mm per axis, RP floor {format_uncertainty(floor_mm)} mm"
    if smallest_rp_mm is None or smallest_rp_mm <= 0:
        return _row("6.5", "sensor", requirement, done, False, "no RP to compare the instrument with")
    share = floor_mm / smallest_rp_mm
    done += f" = {100 * share:.0f} % of the smallest RP"
    # the 25 % rule of thumb of iso9283.md §8.4 [U]
    return _row("6.5", "sensor", requirement, done, share <= 0.25, "RP inflated by the instrument floor")


def _dimensionality(measured: Sequence[str]) -> Deviation:
    requirement = "6-D poses: position x, y, z and orientation a, b, c (7.2) [U]"
    if not measured:
        return _unknown("7.2", "dimensionality", requirement, "measured columns")
    angles = [c for c in measured if c.endswith("_deg")]
    done = f"measured {', '.join(measured)}"
    effect = "orientation AP/RP not reported" if not angles else "orientation only partly measured"
    if not {"x_mm", "y_mm", "z_mm"} <= set(measured):
        effect = "position characteristics in fewer than 3 dimensions; RP not comparable with 3-D RP"
    return _row("7.2", "dimensionality", requirement, done, len(measured) == 6, effect)


def orientation_deviation(angles: Sequence[str], gauge: Mapping[str, float]) -> Deviation:
    """The row of a run whose orientation is read by the calliper tilt gauge (000 §8.2.2, §8.6.3): how the angles
    were measured, and that their budget rests on the bracket's hole spacing."""
    requirement = "orientation a, b, c measured at the attained pose by the pose instrument (7.2.1, 7.2.2) [U]"
    names = ", ".join(angles) or "none"
    done = (
        f"{names} read by a digital calliper at each stop after the position: tilt = atan(Δh / s) from two "
        f"depths through holes s = {gauge['spacing_mm']:g} mm apart (u(s) = {gauge['u_spacing_mm']:.3g} mm), "
        f"calliper resolution {gauge['resolution_mm']:g} mm, MPE ± {gauge['mpe_mm']:g} mm; the source "
        f"dissertation does not state s"
    )
    return _row(
        "7.2.1, 7.2.2",
        "orientation",
        requirement,
        done,
        False,
        "orientation U rests on the stated bracket geometry; only the tested angle is measured",
    )


def _order(config: Mapping[str, Any], protocol: str) -> Deviation:
    requirement = (
        f"cycle order {_ISO_ORDER} (6.10) [U]" if protocol == "iso9283_pose" else "unidirectional approach (6.10) [U]"
    )
    if "poses" not in config:
        return _unknown("6.10", "approach", requirement, "config.poses")
    if config["poses"]:
        return _row(
            "6.10",
            "approach",
            requirement,
            f"order {' -> '.join(config['poses'])}",
            False,
            "approach-dependent errors differ from the ISO sequence",
        )
    done = {
        "iso9283_pose": _ISO_ORDER,
        "iso9283_distance": "P4 <-> P2, starting at P4",
        "iso9283_multidirectional": "pre-poses along -x, -y, -z",
    }.get(protocol, "protocol order")
    return _row("6.10", "approach", requirement, done, True, "")


def _settling(config: Mapping[str, Any]) -> Deviation:
    requirement = "measure once the controller signals the attained pose and it has settled (6.10) [U]"
    if "settle_s" not in config:
        return _unknown("6.10", "settling", requirement, "config.settle_s")
    return _row(
        "6.10",
        "settling",
        requirement,
        f"fixed dwell of {float(config['settle_s']):g} s after each move (no attained-pose signal)",
        False,
        "residual vibration or creep can enter RP",
    )


def _conditioning(config: Mapping[str, Any], clause: str = "6.2/6.3") -> Deviation:
    warm = config.get("warmup_s")
    temperature = config.get("ambient_c")
    done = (
        (f"warm-up {float(warm):g} s" if warm is not None else "no warm-up recorded")
        + "; "
        + (f"ambient {temperature} °C" if temperature is not None else "ambient temperature not recorded")
    )
    return _row(
        clause,
        "conditions",
        "warm-up as specified; ambient temperature recorded [U]",
        done,
        warm is not None and temperature is not None,
        "thermal drift not separable from robot error",
    )


def iso_deviations(
    *,
    protocol: str,
    config: Mapping[str, Any],
    settings: Mapping[str, Any],
    measured_columns: Sequence[str],
    cycles_measured: int,
    instrument_sigma_mm: float | None,
    smallest_rp_mm: float | None,
    rp_floor_mm: float | None,
    allow_unknown: bool = False,
) -> list[Deviation]:
    """The deviations table of one run (iso9283.md §11.2), every clause the run touches.

    Parameters
    ----------
    protocol : str
        Stored protocol name, e.g. ``iso9283_pose``.
    config, settings : mapping
        The run's stored configuration and rig settings (``settings["robot"]``, ``settings["instrument"]``).
    measured_columns : sequence of str
        Attained quantities present in the samples (``x_mm``..., ``a_deg``...).
    cycles_measured : int
        Fewest cycles stored at any pose.
    instrument_sigma_mm, rp_floor_mm : float or None
        Instrument standard uncertainty per axis and its RP floor (None when not stated).
    smallest_rp_mm : float or None
        Smallest RP of the run, for the 25 % rule of thumb.
    allow_unknown : bool
        Keep unknown rows instead of refusing (used only to print what is missing).

    Raises
    ------
    InsufficientData
        When a row is unknown, naming its clause and the missing field.
    """
    robot_settings = settings.get("robot") or {}
    rows = [
        _load(config, robot_settings),
        _velocity(config, robot_settings, protocol),
        *_poses(config),
        _cycles(config, protocol, cycles_measured),
        _order(config, protocol),
        _settling(config),
        _sensor(settings.get("instrument") or {}, instrument_sigma_mm, smallest_rp_mm, rp_floor_mm),
        _dimensionality(measured_columns),
        _conditioning(config),
    ]
    return complete(rows, allow_unknown)


def complete(rows: list[Deviation], allow_unknown: bool) -> list[Deviation]:
    """``rows``, or ``InsufficientData`` naming every unknown row unless ``allow_unknown`` (iso9283.md §11.2)."""
    unknown = [r for r in rows if r.status == "unknown"]
    if unknown and not allow_unknown:
        listed = "; ".join(f"clause {r.clause} {r.topic}: {r.done}" for r in unknown)
        raise InsufficientData(f"deviations table incomplete, refusing to report ({listed})")
    return rows


# ---- the documents' bench tests: the actuator test (000 §8.4), the payload ladder (000 §8.7), grid hits (§8.4.3) ----

# The documents' own figures (travels, loads, lift, heights, attempts, ...) are bench.metrology.documents'.
#: iso9283.md §12.3 [P]: lifts per rung of the payload ladder.
LADDER_MIN_REPEATS = 3


def _floats(values) -> list[float]:
    return [float(v) for v in values]


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
