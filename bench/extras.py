"""Optional dependencies, one home: each extra of ``pyproject.toml`` and the message a user gets without it.

``pip install bench`` alone runs the simulated demo, the analyses and the reports; the camera (OpenCV), the
OS-pointer mouse and keyboard-wedge calliper (pynput), the window (PySide6), the lab store (psycopg), the compiled
kinematics (numba) and Parquet export (pyarrow) are extras. A module that needs one imports it through
:func:`require`, so a missing extra is one line naming what needs it and the command that installs it (exit 2),
never an ImportError traceback.
"""

from __future__ import annotations

import importlib
import importlib.util
from types import ModuleType

from bench.errors import ConfigError

#: import name -> (extra of pyproject.toml, what needs it)
EXTRAS: dict[str, tuple[str, str]] = {
    "cv2": ("camera", "the camera laser-spot sensor"),
    "pynput": ("pointer", "the OS-pointer mouse and the keyboard-wedge calliper"),
    "PySide6": ("gui", "the desktop window"),
    "psycopg": ("lab", "the lab store (PostgreSQL)"),
    "pyarrow": ("parquet", "Parquet export"),
}


def install_hint(module: str) -> str:
    """The one line that says which extra brings ``module``: ``pip install 'bench[camera]'``."""
    extra, purpose = EXTRAS[module]
    return f"{purpose} needs {module}: pip install 'bench[{extra}]'"


def require(module: str) -> ModuleType:
    """Import an optional dependency, or raise :class:`ConfigError` naming the extra that installs it."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise ConfigError(install_hint(module)) from exc


def ensure_installed(module: str) -> None:
    """Raise :class:`ConfigError` naming the extra when ``module`` is not installed, without importing it (some
    modules, pynput among them, fail at import for other reasons, e.g. no display, which the caller reports)."""
    if importlib.util.find_spec(module) is None:
        raise ConfigError(install_hint(module))
