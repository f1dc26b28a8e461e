"""The calliper entry dialog: one manual reading for a protocol's ``Prompt``, validated before it is accepted.

Readings are parsed by :func:`bench.rigs.operators.parse_entry`, the terminal's own parser (sign, ``.`` or ``,``
decimals, ``mm``/``in`` units for lengths, the prompt's bounds), so the window accepts exactly what ``bench``'s
terminal prompt accepts. A keyboard-wedge calliper types its reading
followed by Enter into the focused field, which submits it. A length far from the commanded value (more than
:data:`TOLERANCE_MM`) needs the same value submitted a second time. The reading is stored by the runner the moment
the dialog hands it over. A prompt without a field (an instruction, e.g. "mount 2 kg, then confirm") shows
the instruction with OK / Cancel only.
"""

from __future__ import annotations

from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QKeyEvent
from PySide6.QtWidgets import (
    QDialog,
    QDialogButtonBox,
    QFormLayout,
    QLabel,
    QLineEdit,
    QVBoxLayout,
    QWidget,
)

from bench.errors import ConfigError
from bench.protocols import Prompt
from bench.rigs.operators import TOLERANCE_MM, parse_entry

__all__ = ["TOLERANCE_MM", "CalliperDialog", "parse_entry"]

class CalliperDialog(QDialog):
    """Asks for one reading; emits ``reading_entered(value)`` once the entry is valid (and confirmed).

    Cancelling (Cancel, Esc) emits ``cancelled``: the window withdraws the prompt, and the run ends ``aborted``
    (resumable) with the reason "prompt withdrawn by the operator: ...".
    """

    reading_entered = Signal(float)
    confirmed = Signal()  #: a prompt without a field (an instruction such as "mount 2 kg") was confirmed
    cancelled = Signal()

    def __init__(self, prompt: Prompt, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.prompt = prompt
        self._pending_confirmation: float | None = None
        self.setWindowTitle("Calliper reading" if prompt.field else "Operator confirmation")
        self.setObjectName("calliperDialog")
        layout = QVBoxLayout(self)
        title = QLabel(f"<b>{prompt.text}</b>")
        title.setWordWrap(True)
        layout.addWidget(title)
        form = QFormLayout()
        self.entry = QLineEdit()
        self.entry.setObjectName("readingEntry")
        if prompt.field is not None:
            self._reading_rows(form)
        layout.addLayout(form)
        self.error = QLabel("")
        self.error.setObjectName("readingError")
        self.error.setStyleSheet("color: #b00020")
        self.error.setWordWrap(True)
        layout.addWidget(self.error)
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel)
        buttons.accepted.connect(self.submit)
        buttons.rejected.connect(self.reject)
        layout.addWidget(buttons)
        self.entry.returnPressed.connect(self.submit)  # a keyboard wedge ends its reading with Enter
        self.setWindowModality(Qt.WindowModality.WindowModal)
        self.entry.setFocus()

    def _reading_rows(self, form: QFormLayout) -> None:
        prompt = self.prompt
        bounds = [f"{b:g}" if b is not None else "…" for b in (prompt.minimum, prompt.maximum)]
        form.addRow("Field", QLabel(f"{prompt.field} [{prompt.unit}]"))
        form.addRow("Range", QLabel(f"{bounds[0]} to {bounds[1]} {prompt.unit}"))
        if prompt.commanded:
            form.addRow("Commanded", QLabel(", ".join(f"{k} = {v:g}" for k, v in prompt.commanded.items())))
        self.entry.setPlaceholderText("type the reading or use the calliper's data button, then Enter")
        form.addRow("Reading", self.entry)

    def submit(self) -> None:
        """Validate the entry; emit the reading and close, or show why it was refused."""
        if self.prompt.field is None:
            self.confirmed.emit()
            self.done(QDialog.DialogCode.Accepted)
            return
        try:
            value, question = parse_entry(self.prompt, self.entry.text())
        except ConfigError as exc:
            self._pending_confirmation = None
            self.error.setText(str(exc))
            self.entry.selectAll()
            return
        if question and self._pending_confirmation != value:
            self._pending_confirmation = value
            self.error.setText(question.replace("keep it? [y/N] ", "press Enter again to keep it"))
            return
        self.error.setText("")
        self.reading_entered.emit(value)
        self.done(QDialog.DialogCode.Accepted)

    def keyPressEvent(self, event: QKeyEvent) -> None:
        # Enter belongs to the entry field (one submission per Enter), never to the dialog's default button
        if event.key() not in (Qt.Key.Key_Return, Qt.Key.Key_Enter):
            super().keyPressEvent(event)
        elif self.prompt.field is None:
            self.submit()

    def reject(self) -> None:
        self.cancelled.emit()
        super().reject()
