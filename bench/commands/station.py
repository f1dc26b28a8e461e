"""``bench station check STATION.toml``: open every device of a station and say per device ok / problem / fix.

``--sim`` checks the rehearsal instead (each device replaced by its simulator). Exit 0 when every device is usable,
1 when any is not; ``--json`` prints one object per device.
"""

from __future__ import annotations

import argparse
import json


def register(groups: argparse._SubParsersAction) -> None:
    station = groups.add_parser(
        "station",
        help="bench station files: check the devices a station names",
        description="bench station files (see examples/stations/ and docs/real-bench.md)",
    )
    actions = station.add_subparsers(dest="action", metavar="ACTION", required=True)
    check = actions.add_parser("check", help="open every device, identify the controller, read each sensor once")
    check.add_argument("station", metavar="STATION.toml")
    check.add_argument("--sim", action="store_true", help="check the station's rehearsal on the simulators")
    check.add_argument("--json", action="store_true", help="one JSON object per device, one per line")
    check.set_defaults(handler=_check)


def _check(args: argparse.Namespace) -> int:
    from bench.rigs.check import check_station
    from bench.rigs.station import load_station

    station = load_station(args.station)
    rehearsal = None
    if args.sim:
        from bench.simulators.station import rehearse

        rehearsal = rehearse(station)
        station = rehearsal.station
    try:
        checks = check_station(station)
    finally:
        if rehearsal is not None:
            rehearsal.close()
    for check in checks:
        print(json.dumps(check.as_dict(), sort_keys=True) if args.json else check.line())
    return 0 if all(check.ok for check in checks) else 1
