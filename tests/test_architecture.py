"""The architecture's import contracts (``[tool.importlinter]`` in pyproject.toml), checked on every test run:
production code never imports the simulators, the GUI never imports the command line, motion/ and
bench.metrology stay pure, and the layers import downwards only."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_import_contracts_are_kept():
    lint = Path(sys.executable).with_name("lint-imports")
    result = subprocess.run([str(lint), "--no-cache"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-2000:]
    assert "4 kept, 0 broken" in result.stdout


def test_a_broken_contract_is_caught(tmp_path):
    """The check can fail: a contract that forbids what bench.rigs really imports (its drivers) is reported
    broken."""
    config = tmp_path / "contracts.toml"
    config.write_text('[tool.importlinter]\nroot_packages = ["bench"]\n\n[[tool.importlinter.contracts]]\n'
                      'name = "rigs without robots"\ntype = "forbidden"\nsource_modules = ["bench.rigs"]\n'
                      'forbidden_modules = ["bench.robots"]\n')
    lint = Path(sys.executable).with_name("lint-imports")
    result = subprocess.run([str(lint), "--no-cache", "--config", str(config)], cwd=ROOT, capture_output=True,
                            text=True, timeout=300)
    assert result.returncode == 1 and "rigs without robots BROKEN" in result.stdout
