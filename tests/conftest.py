"""Shared pytest configuration: make the tests folder importable for its small table loaders."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
