"""The Examples sections of the metrology docstrings are run, so the documented numbers stay true."""

import importlib

import pytest
from doctests import run_doctests

import bench.metrology

MODULES = [
    "iso9283",
    "iso9283_dynamics",
    "iso9283_path",
    "actuator",
    "actuator_tables",
    "mouse_calibration",
    "mouse_variance",
    "payload",
    "uncertainty",
    "uncertainty_figures",
    "tables",
    "partial_pose",
    "hit_rate",
]
#: Modules with no Examples section yet (every other module must run at least one example).
WITHOUT_EXAMPLES = {"iso9283_dynamics", "tables"}


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    module = importlib.import_module(f"bench.metrology.{name}")
    result = run_doctests(module)
    assert result.failed == 0
    assert result.attempted > 0 or name in WITHOUT_EXAMPLES


def test_the_package_re_exports_every_module_it_names():
    for name in MODULES:
        if name == "tables":  # the tidy-table interface is imported by module, never re-exported
            continue
        module = importlib.import_module(f"bench.metrology.{name}")
        for public in module.__all__:
            assert getattr(bench.metrology, public) is getattr(module, public), f"{name}.{public}"
    # a submodule stays reachable as an attribute: no re-exported name shadows a module
    assert bench.metrology.hit_rate is importlib.import_module("bench.metrology.hit_rate")
