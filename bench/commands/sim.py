"""``bench sim``: run a simulated robot controller on a pseudo-terminal.

``bench sim pkm5`` / ``bench sim delta4`` run the simulator in this process (a program of its own, separate from
any client): the pty device path is printed on stdout (then the truth-log path with ``--truth``), and it serves
until Ctrl-C or SIGTERM. Connect a driver, a protocol run or a terminal program to the printed path.
"""

from __future__ import annotations

import argparse

from bench.simulators import delta4 as sim_delta4, pkm5 as sim_pkm5
from bench.simulators.pty import run_simulator

_SIMULATORS = {
    "pkm5": (sim_pkm5, "5-DOF PKM controller (line protocol, docs/protocol-pkm5.md)"),
    "delta4": (sim_delta4, "delta4 ATmega128 controller (ASCII protocol, docs/protocol-delta4.md)"),
}


def register(groups: argparse._SubParsersAction) -> None:
    sim = groups.add_parser("sim", help="run a simulated robot controller on a pseudo-terminal")
    robots = sim.add_subparsers(dest="robot", metavar="ROBOT", required=True)
    for name, (module, help_text) in _SIMULATORS.items():
        parser = robots.add_parser(name, help=help_text, description=module.DESCRIPTION,
                                   formatter_class=argparse.ArgumentDefaultsHelpFormatter)
        module.add_arguments(parser)
        parser.set_defaults(handler=lambda args, module=module: run_simulator(module.build_device, args))
