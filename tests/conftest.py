"""Shared pytest configuration: the tests folder is importable for its small helpers, and the desktop-window
fixture ``window`` comes from ``gui_support`` (offscreen Qt)."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

pytest_plugins = ["gui_support"]
