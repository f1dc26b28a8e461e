"""Non-modal message dialogs: a result or an error is shown without blocking the window (and its emergency stop)."""

from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QMessageBox, QWidget

__all__ = ["show_message"]


def show_message(parent: QWidget, icon: QMessageBox.Icon, title: str, text: str, *, name: str) -> QMessageBox:
    """Show ``text`` in a non-modal message box named ``name`` (tests find it by that name) and return it.

    A window that is not shown (closed) gets its message box but shows none: the outcome of work that ended after
    the window closed (an identification it waited for) would otherwise keep the application running, windowless.
    """
    dialog = QMessageBox(icon, title, text, QMessageBox.StandardButton.Ok, parent)
    dialog.setObjectName(name)
    dialog.setWindowModality(Qt.WindowModality.NonModal)
    if parent.window().isVisible():
        dialog.show()
    return dialog
