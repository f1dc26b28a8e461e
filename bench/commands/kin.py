"""``bench kin``: inverse and forward kinematics and workspace of each robot, from the command line.

Every robot has an adapter module ``bench/commands/kin_<robot>.py`` exposing ``add_ik``, ``add_fk`` and
(optionally) ``add_workspace``; each takes the robot-level subparsers of ``bench kin ik|fk|workspace`` and adds
a parser whose ``handler`` returns an exit code. Units on the command line are mm and degrees.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

#: One adapter module per robot; the order is the order of the help.
ROBOT_MODULES = ("bench.commands.kin_pkm5", "bench.commands.kin_delta4", "bench.commands.kin_prus3")

_ACTIONS = {
    "ik": "inverse kinematics: pose -> joint values",
    "fk": "forward kinematics: joint values -> pose",
    "workspace": "workspace volume by Monte Carlo (and convex hull)",
}


def register(groups: argparse._SubParsersAction) -> None:
    kin = groups.add_parser("kin", help="kinematics of the robots (mm, degrees)")
    actions = kin.add_subparsers(dest="action", metavar="ACTION", required=True)
    robots = actions.add_parser("robots", help="list the robots, their pose fields and joints")
    robots.add_argument("--json", action="store_true", help="print the list as one JSON object")
    robots.set_defaults(handler=_list_robots)
    robot_parsers = {}
    for action, text in _ACTIONS.items():
        parser = actions.add_parser(action, help=text)
        robot_parsers[action] = parser.add_subparsers(dest="robot", metavar="ROBOT", required=True)
    for name in ROBOT_MODULES:
        module = importlib.import_module(name)
        for action, robots in robot_parsers.items():
            adder = getattr(module, f"add_{action}", None)
            if adder is not None:
                adder(robots)


def _list_robots(args: argparse.Namespace) -> int:
    from motion.model import robot_models

    listing = {
        name: {
            "pose_fields": list(model.pose_fields),
            "joints": [{"name": j.name, "low": j.low, "high": j.high} for j in model.joints],
        }
        for name, model in robot_models().items()
    }
    emit(
        listing,
        args.json,
        [
            f"{name}: pose ({', '.join(item['pose_fields'])}); joints "
            + ", ".join(f"{j['name']} [{j['low']:g}, {j['high']:g}]" for j in item["joints"])
            for name, item in listing.items()
        ],
    )
    return 0


def emit(result: dict[str, Any], as_json: bool, text_lines: list[str]) -> None:
    """Print a result: JSON on stdout with ``--json``, otherwise the human-readable lines."""
    if as_json:
        json.dump(result, sys.stdout, indent=None, allow_nan=False)
        sys.stdout.write("\n")
    else:
        sys.stdout.write("\n".join(text_lines) + "\n")


def add_sampling_options(parser: argparse.ArgumentParser, samples: int) -> None:
    """The Monte Carlo options every ``bench kin workspace ROBOT`` takes."""
    parser.add_argument("--samples", type=int, default=samples, help="uniform box samples (Monte Carlo)")
    parser.add_argument("--seed", type=int, default=0, help="random seed")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")


@contextmanager
def sampling_progress(args: argparse.Namespace, label: str) -> Iterator[Callable[[int], None] | None]:
    """A ``progress(done)`` callback drawing a Rich bar of ``args.samples`` on stderr (as ``bench run`` does), or
    None with ``--no-progress``. The bar appears only once the work has run ``SHOW_AFTER_S``: short runs stay
    silent."""
    if getattr(args, "no_progress", False):
        yield None
        return
    bar = _DelayedBar(label, args.samples)
    try:
        yield bar.update
    finally:
        bar.close()


#: Work shorter than this shows no progress bar.
SHOW_AFTER_S = 1.0


class _DelayedBar:
    def __init__(self, label: str, total: int) -> None:
        self.label, self.total, self.show_after_s = label, total, SHOW_AFTER_S
        self._started = time.monotonic()
        self._bar: Any = None

    def update(self, done: int) -> None:
        if self._bar is None and time.monotonic() - self._started >= self.show_after_s:
            from bench.protocols.progress import rich_progress

            self._bar = rich_progress()
            self._task = self._bar.add_task(self.label, total=self.total)
            self._bar.start()
        if self._bar is not None:
            self._bar.update(self._task, completed=done)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.stop()


def new_robot_parser(robots: argparse._SubParsersAction, name: str, help_text: str) -> argparse.ArgumentParser:
    """A robot parser with the shared ``--json`` flag and defaults shown in the help."""
    parser = robots.add_parser(name, help=help_text, formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--json", action="store_true", help="print the result as one JSON object")
    return parser
