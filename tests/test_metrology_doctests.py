"""The Examples sections of the metrology docstrings are run, so the documented numbers stay true."""

import doctest
import importlib

import pytest

MODULES = ["iso9283", "iso9283_dynamics", "actuator", "mouse_calibration", "payload", "uncertainty", "tables"]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    module = importlib.import_module(f"bench.metrology.{name}")
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0
