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
from PySide6.QtGui import QCloseEvent, QKeyEvent
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

__all__ = ["TOLERANCE_MM", "CalliperDialog", "parse_entry", "quantity_name"]


class CalliperDialog(QDialog):
    """Asks for one reading; emits ``reading_entered(value)`` once the entry is valid (and confirmed).

    The dialog is non-modal: the main window, and its emergency stop, stay usable while a reading is pending.
    Cancelling (Cancel, Esc) asks first, in the dialog itself: a second Cancel (or Esc) emits ``cancelled``, the
    window withdraws the prompt, and the run ends ``aborted`` (resumable) with the reason "prompt withdrawn by the
    operator: ...". Typing in the field again takes the cancellation back.

    Parameters
    ----------
    number : (k, n) or None
        This is reading ``k`` of the ``n`` readings the run asks for (shown as "Reading k of n").
    """

    reading_entered = Signal(object)  #: an Entry: the value and the text as typed (kept in the store)
    confirmed = Signal()  #: a prompt without a field (an instruction such as "mount 2 kg") was confirmed
    cancelled = Signal()

    def __init__(self, prompt: Prompt, parent: QWidget | None = None, *, number: tuple[int, int] | None = None) -> None:
        super().__init__(parent)
        self.prompt = prompt
        self._pending_confirmation: float | None = None
        self._cancel_pending = False
        self.setWindowTitle("Calliper reading" if prompt.field else "Operator confirmation")
        self.setObjectName("calliperDialog")
        self.setMinimumWidth(480)
        layout = QVBoxLayout(self)
        self.number = QLabel(f"Reading {number[0]} of {number[1]}" if number and prompt.field else "")
        self.number.setObjectName("readingNumber")
        self.number.setVisible(bool(self.number.text()))
        layout.addWidget(self.number)
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
        self.error.setMinimumHeight(3 * self.error.fontMetrics().lineSpacing())  # room kept: no layout jump
        self.error.setAlignment(Qt.AlignmentFlag.AlignTop | Qt.AlignmentFlag.AlignLeft)
        layout.addWidget(self.error)
        self.buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel)
        self.cancel_button = self.buttons.button(QDialogButtonBox.StandardButton.Cancel)
        self.cancel_button.setObjectName("cancelReading")
        self.buttons.accepted.connect(self.submit)
        self.buttons.rejected.connect(self.reject)
        layout.addWidget(self.buttons)
        self.entry.returnPressed.connect(self.submit)  # a keyboard wedge ends its reading with Enter
        self.entry.textEdited.connect(lambda _: self._take_back_cancel())
        self.setWindowModality(Qt.WindowModality.NonModal)  # never blocks the window's emergency stop
        self.entry.setFocus()

    def _reading_rows(self, form: QFormLayout) -> None:
        prompt = self.prompt
        unit = prompt.unit
        bounds = [f"{b:g}" if b is not None else "…" for b in (prompt.minimum, prompt.maximum)]
        form.addRow(
            "Measure", QLabel(f"{quantity_name(prompt.field)} in {unit}" if unit else quantity_name(prompt.field))
        )
        form.addRow("Accepted range", QLabel(f"{bounds[0]} to {bounds[1]} {unit}"))
        expected = prompt.commanded.get(f"cmd_{prompt.field}")
        if expected is not None:
            note = f" (a reading more than {TOLERANCE_MM:g} mm away is asked again)" if unit == "mm" else ""
            label = QLabel(f"{expected:g} {unit}: the value the robot was commanded to{note}")
            label.setWordWrap(True)
            form.addRow("Expected", label)
        others = {k: v for k, v in prompt.commanded.items() if k != f"cmd_{prompt.field}"}
        if others:
            label = QLabel(", ".join(f"{quantity_name(k[4:])} {v:g} {k.rsplit('_', 1)[-1]}" for k, v in others.items()))
            label.setWordWrap(True)
            form.addRow("Commanded pose", label)
        self.entry.setPlaceholderText("type the reading (12,34 or 12.34) or press the calliper's data button")
        form.addRow("Reading", self.entry)

    def submit(self) -> None:
        """Validate the entry; emit the reading and close, or show why it was refused."""
        self._take_back_cancel()
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
        """First Cancel/Esc: say what cancelling does; the second one cancels (the campaign ends, resumable)."""
        if not self._cancel_pending:
            self._cancel_pending = True
            self.error.setText(
                "Cancelling ends the campaign (aborted; it can be resumed later). Press Cancel "
                "(or Esc) again to end it, or type the reading to go on."
            )
            self.cancel_button.setText("End the campaign")
            return
        self.cancelled.emit()
        super().reject()

    def _take_back_cancel(self) -> None:
        if self._cancel_pending:
            self._cancel_pending = False
            self.error.setText("")
            self.cancel_button.setText("Cancel")

    def withdraw(self) -> None:
        """Close without a word: the prompt was withdrawn elsewhere (emergency stop, window closing)."""
        self.blockSignals(True)
        self.done(QDialog.DialogCode.Rejected)

    def closeEvent(self, event: QCloseEvent) -> None:
        """The window manager's close button: the same two-step cancel as Cancel and Esc."""
        event.ignore()
        self.reject()


def quantity_name(field: str) -> str:
    """An operator's name for a stored field: ``length_mm`` -> "length", ``a_deg`` -> "tilt a"."""
    name = field.rsplit("_", 1)[0] if "_" in field else field
    if field.endswith("_deg") and len(name) == 1:
        return f"tilt {name}"
    return name.replace("_", " ")
