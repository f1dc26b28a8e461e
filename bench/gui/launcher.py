"""The start of ``bench gui``: check for a display, show a window at once, then load the main window.

Loading the main window imports the runner, the store, the metrology (SciPy, pandas) and Matplotlib: seconds on a
small machine. A light "loading" window (Qt only) is shown first, so the operator sees the application start
within about a second; without a display the start is refused in one line (:func:`require_display`) instead of
Qt's abort.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from bench.errors import ConfigError

__all__ = ["launch", "require_display"]

#: Qt platforms that need no display server.
_HEADLESS_PLATFORMS = ("offscreen", "minimal", "vnc", "eglfs", "linuxfb", "vkkhrdisplay")


def require_display(environ: dict[str, str] | None = None) -> None:
    """Refuse to start Qt without a display: on Linux, X11 (``DISPLAY``) or Wayland (``WAYLAND_DISPLAY``), unless
    ``QT_QPA_PLATFORM`` names a platform without one (``offscreen``).

    Raises
    ------
    ConfigError
        Naming what is missing and what to do.
    """
    environ = os.environ if environ is None else environ
    platform = environ.get("QT_QPA_PLATFORM", "").split(":")[0]
    if not sys.platform.startswith("linux") or platform in _HEADLESS_PLATFORMS:
        return
    if not environ.get("DISPLAY") and not environ.get("WAYLAND_DISPLAY"):
        raise ConfigError(
            "bench gui: no display (DISPLAY and WAYLAND_DISPLAY are not set); run it in a desktop "
            "session, over ssh -X, or under xvfb-run"
        )


def launch(
    store_path: str | Path = "bench.db", report_dir: str | Path = "reports", argv: list[str] | None = None
) -> int:
    """Open the window and run the Qt event loop until it closes; returns the exit code.

    Raises
    ------
    ConfigError
        There is no display to open the window on (checked before Qt, whose own failure is an abort).
    """
    from PySide6.QtCore import Qt
    from PySide6.QtWidgets import QApplication, QLabel

    if QApplication.instance() is None:
        require_display()
    app = QApplication.instance() or QApplication(argv if argv is not None else sys.argv[:1])
    loading = QLabel(f"bench: opening {store_path} ...\nloading the runner, the store and the metrology")
    loading.setObjectName("benchLoading")
    loading.setWindowTitle("bench")
    loading.setAlignment(Qt.AlignmentFlag.AlignCenter)
    loading.resize(460, 90)
    loading.show()
    app.processEvents()
    from bench.gui.app import MainWindow  # the heavy imports, while the loading window is up

    window = MainWindow(store_path, report_dir)
    window.show()
    loading.close()
    return int(app.exec())
