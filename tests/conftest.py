"""Shared pytest configuration: the tests folder is importable for its small helpers, the desktop-window fixture
``window`` comes from ``gui_support`` (offscreen Qt), simulators are forked from a warm parent
(``zygote``), and the modules with long-running tests run first."""

import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

pytest_plugins = ["gui_support"]

import zygote  # noqa: E402 - after the path above

if os.environ.get("BENCH_TEST_SIMULATOR_FORKS", "1") != "0":  # 0: each simulator a `python -m` of its own
    zygote.install()  # the simulators this process starts are forked from a warm parent


def pytest_collection_modifyitems(config, items):
    """Every module that holds a test marked ``slow`` goes before the others (each keeping its order).

    ``./dev test`` hands whole modules to its two workers in collection order (``--dist loadscope
    --no-loadscope-reorder``): a long module handed out last keeps one worker busy while the other has nothing left,
    so the long ones start at once and the short ones fill the gaps beside them."""
    long_modules = {item.nodeid.split("::")[0] for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: item.nodeid.split("::")[0] not in long_modules)
