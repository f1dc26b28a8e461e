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
from dataclasses import dataclass
from typing import Any

from bench.errors import InsufficientData
from bench.metrology.documents import (
    ISO9283_CYCLES,
    ISO9283_POSE_ORDER,
    ISO9283_VELOCITIES_PCT,
)
from bench.metrology.formatting import format_uncertainty

__all__ = [
    "CLAUSES_APPLIED",
    "ISO_CYCLES",
    "ISO_VELOCITIES_PCT",
    "Deviation",
    "complete",
    "iso_deviations",
    "orientation_deviation",
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


def _floats(values) -> list[float]:
    return [float(v) for v in values]


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
