"""The ``[mice]`` station table: its spec and parser, the mouse calibration a station puts in force, the opener that
makes :class:`bench.rigs.mice.MiceInstrument` of two event devices, and their ``bench station check``.

Registered as the ``mice`` sensor in :mod:`bench.sensor_kinds`; the rig builder and the station file reach it only
through that record.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from bench.errors import ConfigError
from bench.rigs.mice_liveness import XZ_GUIDED, XZ_MOUNTS, XZ_PLATFORM
from bench.sensors.calibration import DEFAULT_CPI

if TYPE_CHECKING:
    from bench.rigs.check import DeviceCheck
    from bench.rigs.mice import MiceInstrument
    from bench.rigs.opening import SensorOpening
    from bench.rigs.station import Station, StationTable
    from bench.sensors.calibration import CountsCalibration

__all__ = ["MiceSpec", "calibration_summary", "check_mice", "mouse_calibration", "open_mice", "parse_mice"]

_log = logging.getLogger(__name__)


#: The resolutions a station may state (counts per inch) [choice: optical mouse sensors span about 200-26,000 cpi;
#: a figure outside 100-50,000 is a typo (1e20 was accepted and every reading became 0 mm)].
MIN_CPI, MAX_CPI = 100.0, 50_000.0


@dataclass(frozen=True)
class MiceSpec:
    """Two optical mice by event device: ``xy`` measures x and y, ``xz`` measures x and z (z only on guides)."""

    xy: str
    xz: str
    cpi: float = DEFAULT_CPI
    noise_counts: float | None = None  #: reading noise per count, when measured; stated in the report's budget
    grab: bool = True  #: take the mice exclusively (EVIOCGRAB) so the desktop pointer does not move
    #: the stored ``mouse`` calibration version in force; None: the nominal ``cpi`` (a stored one is never put in
    #: force because it is the newest)
    calibration: int | None = None
    #: how the x-z mouse is mounted: ``"platform"`` (on the end effector: sees x and z) or ``"guided"`` (on a
    #: platform of its own on vertical guides, pushed by the end effector: sees z only, the dissertation's Z mouse)
    xz_mount: str = XZ_PLATFORM


def parse_mice(table: StationTable) -> MiceSpec:
    """``[mice]`` of a station file (``xy``, ``xz``, ``cpi``, ``noise_counts``, ``grab``, ``calibration``,
    ``xz_mount``)."""
    expected = "a stored mouse calibration version, an integer >= 1"
    version = table.get("calibration", int, None, expected=expected)
    if version is not None and version < 1:
        raise table.fail("calibration", version, expected)
    mount_expected = '"platform" (on the end effector: sees x and z) or "guided" (on vertical guides: sees z only)'
    xz_mount = table.get("xz_mount", str, XZ_PLATFORM, expected=mount_expected)
    if xz_mount not in XZ_MOUNTS:
        raise table.fail("xz_mount", xz_mount, mount_expected)
    cpi = table.number("cpi", DEFAULT_CPI)
    if not MIN_CPI <= cpi <= MAX_CPI:
        raise table.fail("cpi", cpi, f"a mouse's resolution in counts per inch, {MIN_CPI:g} to {MAX_CPI:g}")
    return MiceSpec(
        xy=table.get("xy", str, required=True, expected="the x-y mouse's event device"),
        xz=table.get("xz", str, required=True, expected="the x-z mouse's event device"),
        cpi=cpi,
        noise_counts=table.number("noise_counts", None, zero_allowed=True),
        grab=table.get("grab", bool, True),
        calibration=version,
        xz_mount=xz_mount,
    )


def mouse_calibration(
    store: Any, cpi: float, version: int | None = None, *, source: str = "station"
) -> tuple[Any, CountsCalibration]:
    """The mouse calibration a station puts in force; returns (store record, :class:`CountsCalibration`).

    With ``version`` (``[mice] calibration``), that stored ``mouse`` calibration, per-axis scales where it has
    them; without, the nominal resolution at ``cpi``, recorded once and flagged nominal (a later nominal run reuses
    that record, even after a measured calibration was stored). A measured calibration is never
    put in force because it is the newest: a warning names the newest measured one and the key that would use it.
    """
    from bench.sensors.calibration import MM_PER_INCH, CountsCalibration

    if version is not None:
        try:
            record = store.calibration("mouse", version)
        except ConfigError:
            stored = [str(c.version) for c in store.calibrations() if c.name == "mouse"]
            raise ConfigError(
                f"{source}: mice.calibration = {version}, expected a stored mouse calibration version "
                f"({', '.join(stored) or 'none stored yet'})"
            ) from None
    else:
        mouse_versions = [c for c in store.calibrations() if c.name == "mouse"]
        measured = [c for c in mouse_versions if not c.params.get("nominal")]
        nominal = {"mm_per_count": MM_PER_INCH / cpi, "nominal": True}
        # the nominal record of this cpi once, whatever was stored after it: a measured calibration stored since
        # would otherwise make each nominal run write a new version, newer than the measured one
        same = [c for c in mouse_versions if c.params == nominal]
        record = (
            same[-1]
            if same
            else store.ensure_calibration("mouse", nominal, notes=f"nominal {cpi:g} cpi (no [mice] calibration named)")
        )
        if measured:
            _log.warning(
                "%s: the nominal %g cpi is in force; stored calibration mouse-v%d is not used unless the "
                "station names it ([mice] calibration = %d)",
                source,
                cpi,
                measured[-1].version,
                measured[-1].version,
            )
    params = record.params
    matrix = params.get("matrix_mm_per_count") or np.diag(
        [params.get(f"{axis}_mm_per_count", params["mm_per_count"]) for axis in "xy"]
    )
    calibration = CountsCalibration(
        np.asarray(matrix, dtype=float),
        f"mouse-v{record.version}",
        record.created_utc[:10],
        nominal=bool(params.get("nominal", False)),
    )
    return record, calibration


def calibration_summary(record: Any) -> dict[str, Any]:
    """What a run records of the mouse calibration it used: version, nominal or not, and each scale with its u."""
    params = record.params
    summary: dict[str, Any] = {"version": record.version, "nominal": bool(params.get("nominal", False))}
    for axis in ("x", "y"):
        summary[f"{axis}_mm_per_count"] = params.get(f"{axis}_mm_per_count", params["mm_per_count"])
        if f"u_{axis}_mm_per_count" in params:
            summary[f"u_{axis}_mm_per_count"] = params[f"u_{axis}_mm_per_count"]
    return summary


def open_mice(opening: SensorOpening) -> MiceInstrument:
    """The two mice as the rig's instrument, read through the calibration in force (its id recorded with the run);
    zeroed at the home pose (the builder homed the robot), then verified at the check pose (the registration)."""
    from bench.rigs.mice import MiceInstrument
    from bench.sensors.mouse import EvdevMouse

    spec: MiceSpec = opening.spec
    record, calibration = mouse_calibration(opening.store, spec.cpi, spec.calibration, source=opening.station.source)
    opening.calibration_ids.append(record.id)
    mice = {}
    for plane, path in (("xy", spec.xy), ("xz", spec.xz)):
        mice[plane] = EvdevMouse(path, calibration, label=f"mouse_{plane}", grab=spec.grab)
        opening.opened.callback(mice[plane].close)
    instrument = MiceInstrument(
        mice,
        opening.home(),
        calibration,
        follow=True,
        noise_counts=spec.noise_counts,
        calibration_record=calibration_summary(record),
        xz_mount=spec.xz_mount,
        time_scale=opening.speed_factor,
    )
    if spec.xz_mount == XZ_GUIDED:
        _log.info(
            "%s: the x-z mouse is on vertical guides (xz_mount = %r): it is judged on the commanded z alone, and a "
            "slip along x is caught by the commanded-move rule only (no x cross-check)",
            opening.station.source,
            spec.xz_mount,
        )
    opening.opened.callback(instrument.close)
    return instrument


def check_mice(station: Station, spec: MiceSpec) -> list[DeviceCheck]:
    """Each mouse opened (grabbed as a run would), its waiting reports counted, and closed."""
    from functools import partial

    from bench.rigs.check import guarded

    return [
        guarded(f"mice.{plane}", path, "input", partial(_mouse, path, spec.grab))
        for plane, path in (("xy", spec.xy), ("xz", spec.xz))
    ]


def _mouse(path: str, grab: bool) -> str:
    from bench.sensors.calibration import CountsCalibration
    from bench.sensors.mouse import EvdevMouse

    with EvdevMouse(path, CountsCalibration.from_cpi(DEFAULT_CPI), label=path, grab=grab) as mouse:
        frames = mouse.read_frames()
        kind = "event device" if mouse.binding.is_device else "FIFO or file (not an event device)"
        return f"{kind} {mouse.binding.name or ''}".rstrip() + f", {len(frames)} reports waiting"
