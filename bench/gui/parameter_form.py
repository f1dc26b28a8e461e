"""A form for a protocol's typed parameters, validated field by field with the parameters' own ``convert``.

Each parameter gets a field showing its TOML value (``[100, 50]``, ``"xy"``, ``50 mm``); the text is read as a
TOML value (or kept as text, so ``50 mm`` goes to the parameter's unit check) and handed to
:meth:`bench.protocols.parameters.Parameter.convert`, which gives the same message as a bad TOML file. The whole
configuration is then built by :func:`bench.protocols.protocol_from_config`, so cross-parameter checks apply too.
An empty field means the parameter's default.
"""

from __future__ import annotations

import json
import tomllib
from typing import Any

from PySide6.QtCore import Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFormLayout,
    QLabel,
    QLineEdit,
    QWidget,
)

from bench.errors import ConfigError
from bench.protocols import Protocol, protocol_from_config
from bench.protocols.parameters import BoolParameter, ChoiceParameter, Parameter

__all__ = ["ParameterForm", "parse_field", "show_value"]


def show_value(value: Any) -> str:
    """A parameter value as the TOML text the form shows ('' for None)."""
    if value is None:
        return ""
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {show_value(v)}" for k, v in value.items()) + "}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(show_value(v) for v in value) + "]"
    if isinstance(value, float):
        return f"{value:g}"
    return json.dumps(value)


def parse_field(text: str) -> Any:
    """The TOML value typed in a field, or the text itself when it is not one (``50 mm``)."""
    try:
        return tomllib.loads(f"value = {text}")["value"]
    except tomllib.TOMLDecodeError:
        return text.strip()


class ParameterForm(QWidget):
    """Editable parameters of one protocol; ``changed(protocol_or_None, errors)`` after every edit."""

    changed = Signal(object, list)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.layout_ = QFormLayout(self)
        self.fields: dict[str, QWidget] = {}
        self.errors: dict[str, QLabel] = {}
        self.protocol: Protocol | None = None
        self._base: dict[str, Any] = {}
        self.fixed: dict[str, Any] = {}
        self.source = "parameters"

    def load(self, protocol: Protocol, *, fixed: dict[str, Any] | None = None) -> None:
        """Show ``protocol``'s parameters; ``fixed`` values (the robot chosen in the robot panel) are not editable."""
        while self.layout_.rowCount():
            self.layout_.removeRow(0)
        self.fields, self.errors = {}, {}
        self.fixed = dict(fixed or {})
        self._base = {"protocol": protocol.name}
        self.source = protocol.source
        title = QLabel(f"<b>{protocol.name}</b> v{protocol.version}: {protocol.title}")
        title.setWordWrap(True)
        self.layout_.addRow(title)
        for name, parameter in protocol.parameters().items():
            widget = self._field(parameter, getattr(protocol, name))
            widget.setToolTip(parameter.help())
            widget.setEnabled(name not in self.fixed)
            error = QLabel("")
            error.setStyleSheet("color: #b00020")
            error.setWordWrap(True)
            error.hide()
            unit = f" ({parameter.unit})" if parameter.unit else ""
            self.layout_.addRow(f"{name}{unit}", widget)
            self.layout_.addRow("", error)
            self.fields[name], self.errors[name] = widget, error
        self.validate()

    def _field(self, parameter: Parameter, value: Any) -> QWidget:
        if isinstance(parameter, ChoiceParameter):
            widget = QComboBox()
            widget.addItems(list(parameter.choices))
            widget.setCurrentText(value)
            widget.currentTextChanged.connect(self.validate)
        elif isinstance(parameter, BoolParameter):
            widget = QCheckBox()
            widget.setChecked(bool(value))
            widget.toggled.connect(self.validate)
        else:
            widget = QLineEdit(show_value(value))
            widget.textChanged.connect(self.validate)
        return widget

    def values(self) -> dict[str, Any]:
        """The raw values typed (TOML-parsed), empty fields left out."""
        out: dict[str, Any] = {}
        for name, widget in self.fields.items():
            if isinstance(widget, QComboBox):
                out[name] = widget.currentText()
            elif isinstance(widget, QCheckBox):
                out[name] = widget.isChecked()
            elif widget.text().strip():
                out[name] = parse_field(widget.text())
        return {**out, **self.fixed}

    def set_value(self, name: str, text: str) -> None:
        """Type ``text`` into field ``name`` (for scripted use and tests)."""
        widget = self.fields[name]
        if isinstance(widget, QComboBox):
            widget.setCurrentText(text)
        elif isinstance(widget, QCheckBox):
            widget.setChecked(text.lower() == "true")
        else:
            widget.setText(text)

    def validate(self) -> Protocol | None:
        """Check every field, then the whole protocol; emit ``changed`` and return the protocol or None."""
        values, messages = self.values(), []
        for name, error in self.errors.items():
            try:
                if name in values:
                    self._parameter(name).convert(values[name], self.source)
                error.hide()
            except ConfigError as exc:
                error.setText(str(exc))
                error.show()
                messages.append(str(exc))
        protocol = None
        if not messages:
            try:
                protocol = protocol_from_config({**self._base, **values}, source=self.source)
            except ConfigError as exc:
                messages.append(str(exc))
        self.protocol = protocol
        self.changed.emit(protocol, messages)
        return protocol

    def _parameter(self, name: str) -> Parameter:
        from bench.protocols import PROTOCOLS

        return PROTOCOLS[self._base["protocol"]].parameters()[name]
