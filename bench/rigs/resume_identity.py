"""A resumed run continues on the rig it ran on: another device under test, robot, station or the simulator in
place of hardware (or the reverse) is refused in one line naming both, before anything is opened or written.

What a run ran on is in its stored settings: ``station`` (the station's settings, with its ``identity``: bench
name, robot serial or asset) for a station or ``--port`` run, ``simulator`` for any simulated one (the default rig
or a station's rehearsal). A resume that would silently mix samples of two robots, or simulated samples into a
real run, gives numbers nobody can sign.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from bench.errors import ConfigError
from bench.rigs.station import Station

__all__ = ["refuse_another_rig"]


def _dut(identity: Mapping[str, Any]) -> str:
    """The device under test of a station identity (its serial, else its asset number; '' when neither)."""
    return identity.get("robot_serial") or identity.get("robot_asset") or ""


def _describe(station_settings: Mapping[str, Any] | None, simulated: bool) -> str:
    if station_settings is None:
        return "the simulator (--sim)" if simulated else "no station"
    where = f"station {station_settings.get('source', '?')}"
    return where + (" rehearsed on simulators (--sim)" if simulated else " (hardware)")


#: The ``source`` a station made from ``--port`` (and the mice options) carries: the CLI's and the window's label.
_PORT_SOURCES = ("--port", "serial port")


def _rig_options(station_settings: Mapping[str, Any] | None, simulated: bool) -> str:
    """The rig options that name the rig a run ran on, for the operator to add to ``bench resume``."""
    if station_settings is None:
        return "--sim"
    source = str(station_settings.get("source", "STATION.toml"))
    if source in _PORT_SOURCES:
        return "--port PORT (the controller it ran on, with its mice)"
    return f"--station {source}" + (" --sim" if simulated else "")


def refuse_another_rig(
    run: str, stored: Mapping[str, Any], station: Station | None, simulate: bool, *, named: bool = True
) -> None:
    """Raise ``ConfigError`` when the rig asked for (``station``, rehearsed when ``simulate``; None: the simulated
    default rig) is not the one run ``run`` ran on (its stored ``settings``). ``named``: the request named a rig
    (--station, --port or --sim); a bare ``bench resume RUN`` is told so, not that it asked for the simulator.

    Compared: simulated or hardware, station or none, the device under test (serial or asset), the robot's asset
    number and the bench (the station's name). A station file moved or renamed is fine when these agree. Every refusal names the options
    that resume the run on its own rig.
    """
    was_station = stored.get("station")
    was_simulated = "simulator" in stored
    now_simulated = station is None or simulate
    now_station = None if station is None else station.settings()
    options = _rig_options(was_station, was_simulated)
    if (was_station is None) != (now_station is None) or was_simulated != now_simulated:
        asked = f"resume asked for {_describe(now_station, now_simulated)}" if named else "resume named no rig"
        raise ConfigError(
            f"{run}: ran on {_describe(was_station, was_simulated)}, {asked}; resume it on the rig it ran on: {options}"
        )
    if was_station is None or now_station is None:
        return
    before, after = was_station.get("identity", {}), now_station["identity"]
    for what, was, now in (
        ("device under test", _dut(before), _dut(after)),
        # the asset number names the robot too: another one beside the same serial is another robot or a typo
        ("robot asset", before.get("robot_asset", ""), after.get("robot_asset", "")),
        ("bench", before.get("bench", ""), after.get("bench", "")),
        ("robot", was_station.get("robot", ""), now_station["robot"]),
    ):
        if was != now:
            raise ConfigError(
                f"{run}: {what} is {was or '(none named)'}, the station {now_station['source']} "
                f"names {now or '(none)'}; resume it with the station it ran on: {options}"
            )
