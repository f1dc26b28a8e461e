"""Operators: who answers a run's prompts. The person at the terminal (:class:`ConsoleOperator`); the desktop
window brings its own (:mod:`bench.gui`); a serial gauge answers the readings itself (:mod:`bench.rigs.gauges`)."""

from __future__ import annotations

from collections.abc import Callable

from bench.errors import PromptWithdrawn
from bench.steps import Prompt

__all__ = ["ConsoleOperator"]


class ConsoleOperator:
    """Asks the person at the terminal (prompt on stderr, answer on stdin), re-asking until the value is valid."""

    def __init__(self, read_line: Callable[[str], str] = input) -> None:
        self.read_line = read_line

    def ask(self, prompt: Prompt) -> float | None:
        import sys

        while True:
            unit = f" [{prompt.unit}]" if prompt.unit else ""
            print(f"{prompt.text}{unit}: " if prompt.field else f"{prompt.text} (Enter): ", end="", file=sys.stderr,
                  flush=True)
            try:
                text = self.read_line("").strip()
            except EOFError:  # Ctrl-D: the operator withdraws the prompt; the run stays resumable
                raise PromptWithdrawn("end of input (Ctrl-D) at the terminal") from None
            if prompt.field is None:
                return None
            try:
                value = float(text)
                low, high = prompt.minimum, prompt.maximum
                if (low is not None and value < low) or (high is not None and value > high):
                    raise ValueError
                return value
            except ValueError:
                print(f"  {prompt.field} = {text!r}, expected a number in [{prompt.minimum}, {prompt.maximum}]"
                      f"{unit}; try again", file=sys.stderr)


