"""bench.gui: the desktop window (PySide6) onto bench's runner, store, metrology and reports.

``bench gui`` opens :class:`~bench.gui.app.MainWindow`: a robot panel (connect, pre-flight-checked jog, emergency
stop), a campaign panel (protocol file, validated parameter form, pre-flight and duration, queue, start / pause /
resume / stop / abort, progress with ETA), a live view (attained points per pose with barycentre and RP circle,
sensor stream), a calliper dialog for manual readings, and a results browser (status, report, comparison,
resume, export). Campaigns run in a QThread (:class:`~bench.gui.worker.CampaignWorker`) that talks to the window
only through signals. Nothing here computes a result: the window presents what the CLI's code paths produce.
"""

from bench.gui.launcher import launch, require_display

__all__ = ["MainWindow", "launch", "require_display"]


def __getattr__(name: str):
    if name == "MainWindow":  # loaded on first use: ``bench gui`` shows its loading window before these imports
        from bench.gui.app import MainWindow

        return MainWindow
    raise AttributeError(f"module 'bench.gui' has no attribute {name!r}")
