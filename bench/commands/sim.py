"""``bench sim``: run a simulated robot controller on a pseudo-terminal.

``bench sim pkm5`` / ``bench sim delta4`` run the simulator in this process (a program of its own, separate from
any client): the pty device path is printed on stdout (then the truth-log path with ``--truth``), and it serves
until Ctrl-C or SIGTERM. Connect a driver, a protocol run or a terminal program to the printed path.
"""

from __future__ import annotations

import argparse
import importlib

from bench.commands.lazy import defer

#: Robot -> (simulator module, help); the module (numpy, the plant) is imported when its command is parsed.
_SIMULATORS = {
    "pkm5": ("bench.simulators.pkm5", "5-DOF PKM controller (line protocol, docs/protocol-pkm5.md)"),
    "delta4": ("bench.simulators.delta4", "delta4 ATmega128 controller (ASCII protocol, docs/protocol-delta4.md)"),
}


def register(groups: argparse._SubParsersAction) -> None:
    sim = groups.add_parser("sim", help="run a simulated robot controller on a pseudo-terminal")
    robots = sim.add_subparsers(dest="robot", metavar="ROBOT", required=True)
    for name, (module_name, help_text) in _SIMULATORS.items():
        parser = robots.add_parser(name, help=help_text, formatter_class=argparse.ArgumentDefaultsHelpFormatter)
        defer(parser, lambda parser, module_name=module_name: _add_simulator_arguments(parser, module_name))


def _add_simulator_arguments(parser: argparse.ArgumentParser, module_name: str) -> None:
    from bench.simulators.pty import run_simulator

    module = importlib.import_module(module_name)
    parser.description = module.DESCRIPTION
    module.add_arguments(parser)
    parser.set_defaults(handler=lambda args: run_simulator(module.build_device, args))
