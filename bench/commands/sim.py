"""``bench sim``: run a simulated robot controller on a pseudo-terminal.

``bench sim pkm5`` / ``bench sim delta4`` run the simulator in this process (a program of its own, separate from
any client): the pty device path is printed on stdout (then the truth-log path with ``--truth``), and it serves
until Ctrl-C or SIGTERM. Connect a driver, a protocol run or a terminal program to the printed path.
"""

from __future__ import annotations

import argparse
import importlib

from bench.commands.lazy import defer
from bench.robot_kinds import ROBOT_KINDS


def register(groups: argparse._SubParsersAction) -> None:
    sim = groups.add_parser("sim", help="run a simulated robot controller on a pseudo-terminal")
    robots = sim.add_subparsers(dest="robot", metavar="ROBOT", required=True)
    for name, kind in ROBOT_KINDS.items():  # the simulator module (numpy, the plant) is imported when parsed
        parser = robots.add_parser(
            name, help=kind.simulator_help, formatter_class=argparse.ArgumentDefaultsHelpFormatter
        )
        defer(parser, lambda parser, module_name=kind.simulator: _add_simulator_arguments(parser, module_name))


def _add_simulator_arguments(parser: argparse.ArgumentParser, module_name: str) -> None:
    from bench.simulators.pty import run_simulator

    module = importlib.import_module(module_name)
    parser.description = module.DESCRIPTION
    module.add_arguments(parser)
    parser.set_defaults(handler=lambda args: run_simulator(module.build_device, args))
