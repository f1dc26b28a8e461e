"""Operators: who answers a run's prompts. The person at the terminal (:class:`ConsoleOperator`); the desktop
window brings its own (:mod:`bench.gui`); a serial gauge answers the readings itself (:mod:`bench.rigs.gauges`).

Every typed reading, at the terminal or in the window, goes through one parser, :func:`parse_entry`: a sign,
digits with ``.`` or ``,`` as decimal separator, an optional unit (``mm``, ``in``/``"`` for lengths; the prompt's
own unit otherwise); never NaN or infinity; the prompt's bounds; and a confirmation question when a length is far
from the commanded one.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Callable

from bench.errors import ConfigError, PromptWithdrawn
from bench.rigs.interfaces import Entry
from bench.sensors.calliper import ReadingRequest, parse_length
from bench.sensors.reading import MalformedSample
from bench.steps import Prompt

__all__ = ["TOLERANCE_MM", "ConsoleOperator", "parse_entry"]

#: A typed length this far from the commanded one is asked to be confirmed (a misread digit), mm.
TOLERANCE_MM = 2.0


def _request(prompt: Prompt) -> ReadingRequest:
    expected = next((v for k, v in prompt.commanded.items() if k == f"cmd_{prompt.field}"), None)
    return ReadingRequest(
        prompt.text,
        min_mm=-float("inf") if prompt.minimum is None else prompt.minimum,
        max_mm=float("inf") if prompt.maximum is None else prompt.maximum,
        expected_mm=expected if prompt.unit == "mm" else None,
        tolerance_mm=TOLERANCE_MM,
    )


def parse_entry(prompt: Prompt, text: str) -> tuple[Entry, str]:
    """The reading typed for ``prompt`` (an :class:`Entry` keeping ``text`` as typed, stripped) and a confirmation
    question ('' when plausible).

    Lengths (``prompt.unit == "mm"``) accept what a calliper or a wedge types (``12,34``, ``0.4865 in``); other
    units accept a number with an optional trailing unit equal to the prompt's (``-1,5 deg``), and a prompt without
    unit a bare number.

    Raises
    ------
    ConfigError
        Naming the prompt, the text or value, and what was expected.
    """
    typed = text.strip()
    if prompt.unit != "mm":  # only lengths convert units; a count's "3 in" is no count of 76.2
        text = re.sub(rf"\s*{re.escape(prompt.unit)}\s*$", "", typed) if prompt.unit else typed
        if re.search(r"[A-Za-z\"]", text):
            wanted = f"a number, optionally followed by {prompt.unit}" if prompt.unit else "a number without unit"
            raise ConfigError(
                f"{prompt.text}: {text!r} is not a reading{f' in {prompt.unit}' if prompt.unit else ''}"
                f"; expected {wanted}"
            )
    try:
        value = parse_length(text, source=prompt.text)
    except MalformedSample as exc:
        raise ConfigError(str(exc)) from exc
    try:
        question = _request(prompt).check(value)
    except ConfigError as exc:
        raise ConfigError(str(exc).replace(" mm", f" {prompt.unit}") if prompt.unit != "mm" else str(exc)) from exc
    return Entry(value, typed), question


class ConsoleOperator:
    """Asks the person at the terminal (prompt on stderr, answer on stdin), re-asking until the entry is valid; a
    length far from the commanded one is kept only when the person confirms it."""

    def __init__(self, read_line: Callable[[str], str] = input) -> None:
        self.read_line = read_line

    def _line(self) -> str:
        try:
            return self.read_line("").strip()
        except EOFError:  # Ctrl-D or a closed stdin: the operator withdraws the prompt; the run stays resumable
            raise PromptWithdrawn("end of input (Ctrl-D) at the terminal") from None

    def ask(self, prompt: Prompt) -> float | None:
        unit = f" [{prompt.unit}]" if prompt.unit else ""
        while True:
            print(
                f"{prompt.text}{unit}: " if prompt.field else f"{prompt.text} (Enter): ",
                end="",
                file=sys.stderr,
                flush=True,
            )
            text = self._line()
            if prompt.field is None:
                return None
            try:
                value, question = parse_entry(prompt, text)
            except ConfigError as exc:
                print(f"  {exc}; try again", file=sys.stderr)
                continue
            if not question:
                return value
            print(f"  {question.strip()} ", end="", file=sys.stderr, flush=True)
            if self._line().lower() in ("y", "yes"):
                return value
