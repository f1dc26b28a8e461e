"""Typed protocol parameters: descriptors with unit, bounds, default and description, checked on assignment.

A protocol declares its parameters as class attributes (as PyMeasure procedures do); every value a TOML file or
the command line gives goes through :meth:`Parameter.convert`, and a bad one raises ``ConfigError`` naming the
place, the field, the value and the expectation, e.g. ``pose_test.toml: cycles = 0, expected an integer in [2, 100000]``.
A number may carry its unit as a string (``"50 mm"``); a wrong unit is refused, never converted silently.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from typing import Any

from bench.errors import ConfigError

__all__ = [
    "BoolParameter",
    "ChoiceParameter",
    "FloatListParameter",
    "FloatParameter",
    "IntegerParameter",
    "MAX_COUNT",
    "MAX_PLAN_REPEATS",
    "Parameter",
    "PoseTableParameter",
    "TextParameter",
]

_NUMBER_WITH_UNIT = re.compile(r"^\s*([-+0-9.eE]+)\s*([A-Za-z%/]+)?\s*$")

#: The largest count (cycles, repeats, attempts) an integer parameter takes unless it states its own maximum:
#: 100 000 cycles of one pose at a second each is more than a day of one bench; an absurd size (``1e20``) is
#: refused in one line before any plan is built, never iterated.
MAX_COUNT = 100_000

#: The largest product of a protocol's sizes (its counts, the lengths of its lists and pose tables) a file may ask
#: for: each size alone is bounded, their product is what a plan repeats. Beyond it (``cycles = 100000`` with 1 000
#: velocities: 5 x 10^9 steps, hours of dry run) the protocol is refused in one line before a plan exists
#: (:meth:`bench.protocols.base.Protocol.refuse_absurd_plan`); 10 times :data:`MAX_COUNT` leaves every documented
#: design room (ISO 9283: 30 cycles x 3 velocities x 2 loads).
MAX_PLAN_REPEATS = 1_000_000


class Parameter:
    """Base descriptor: ``default``, ``unit``, ``description``; subclasses define ``_convert`` and ``expected``."""

    def __init__(self, default: Any, *, unit: str | None = None, description: str = "") -> None:
        self.unit = unit
        self.description = description
        self.name = "?"
        self.default = default

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name
        if self.default is not None:
            self.default = self.convert(self.default, f"{owner.__name__} default")

    def __get__(self, instance: Any, owner: type | None = None) -> Any:
        if instance is None:
            return self
        return instance.__dict__.get(self.name, self.default)

    def __set__(self, instance: Any, value: Any) -> None:
        instance.__dict__[self.name] = self.convert(value, getattr(instance, "source", "parameter"))

    @property
    def expected(self) -> str:
        raise NotImplementedError

    def convert(self, value: Any, source: str) -> Any:
        """The checked value; ``ConfigError`` naming ``source``, the field and the expectation otherwise."""
        try:
            return self._convert(value)
        except (TypeError, ValueError) as exc:
            raise ConfigError(f"{source}: {self.name} = {_show(value)}, expected {self.expected}") from exc

    def _convert(self, value: Any) -> Any:
        raise NotImplementedError

    def plan_factor(self, value: Any) -> int:
        """How many times a plan repeats for this parameter's ``value`` (1: it sizes nothing)."""
        return 1

    def help(self) -> str:
        """One line for ``--dry-run`` and docs: name, default, unit, description."""
        unit = f" {self.unit}" if self.unit else ""
        return f"{self.name} = {_show(self.default)}{unit}: {self.description}"


def _show(value: Any) -> str:
    return repr(value) if isinstance(value, str) else str(value).replace("'", '"')


def _bounds_text(minimum: float | None, maximum: float | None, unit: str | None) -> str:
    unit_text = f" {unit}" if unit and unit != "%" else (unit or "")
    if minimum is not None and maximum is not None:
        return f" in [{minimum:g}, {maximum:g}]{unit_text}"
    if minimum is not None:
        return f" >= {minimum:g}{unit_text}"
    if maximum is not None:
        return f" <= {maximum:g}{unit_text}"
    return f" in {unit}" if unit else ""


class _Bounded(Parameter):
    def __init__(
        self,
        default: Any,
        *,
        unit: str | None = None,
        minimum: float | None = None,
        maximum: float | None = None,
        description: str = "",
    ) -> None:
        self.minimum = minimum
        self.maximum = maximum
        super().__init__(default, unit=unit, description=description)

    def _number(self, value: Any) -> float:
        if isinstance(value, bool):
            raise TypeError("a boolean is not a number")
        if isinstance(value, str):
            match = _NUMBER_WITH_UNIT.match(value)
            if not match or (match.group(2) or self.unit) != self.unit:
                raise ValueError("wrong unit or not a number")
            value = float(match.group(1))
        number = float(value)
        if not math.isfinite(number):
            raise ValueError("not finite")
        if (self.minimum is not None and number < self.minimum) or (self.maximum is not None and number > self.maximum):
            raise ValueError("out of bounds")
        return number


class IntegerParameter(_Bounded):
    """An integer, e.g. ``cycles = IntegerParameter(30, minimum=2)``; at most :data:`MAX_COUNT` unless ``maximum``
    says otherwise (a count bounds a plan's size)."""

    def __init__(self, default: Any, *, maximum: float | None = MAX_COUNT, counts: bool = True, **kwargs: Any) -> None:
        self.counts = counts  # False for a number that sizes nothing (a seed)
        super().__init__(default, maximum=maximum, **kwargs)

    def plan_factor(self, value: Any) -> int:
        return int(value) if self.counts and value is not None else 1

    @property
    def expected(self) -> str:
        return "an integer" + _bounds_text(self.minimum, self.maximum, self.unit)

    def _convert(self, value: Any) -> int:
        number = self._number(value)
        if number != int(number) or (isinstance(value, float) and not value.is_integer()):
            raise ValueError("not an integer")
        return int(number)


class FloatParameter(_Bounded):
    """A real number with unit, e.g. ``settle_s = FloatParameter(1.0, unit="s", minimum=0)``."""

    @property
    def expected(self) -> str:
        return "a number" + _bounds_text(self.minimum, self.maximum, self.unit)

    def _convert(self, value: Any) -> float:
        return self._number(value)


class FloatListParameter(_Bounded):
    """A non-empty list of numbers with a common unit and bounds, e.g. velocities ``[100, 50, 10]`` %."""

    def __init__(self, default: Sequence[float], *, length: int | None = None, **kwargs: Any) -> None:
        self.length = length
        super().__init__(default, **kwargs)

    @property
    def expected(self) -> str:
        count = f"{self.length} numbers" if self.length else "a non-empty list of numbers"
        return count + _bounds_text(self.minimum, self.maximum, self.unit)

    def _convert(self, value: Any) -> tuple[float, ...]:
        if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) or not value:
            raise TypeError("not a list")
        if self.length is not None and len(value) != self.length:
            raise ValueError("wrong length")
        return tuple(self._number(item) for item in value)

    def plan_factor(self, value: Any) -> int:
        return len(value) if self.length is None and value else 1  # a fixed-length list is one point, not a series


class BoolParameter(Parameter):
    """``true`` or ``false``."""

    expected = "true or false"

    def _convert(self, value: Any) -> bool:
        if not isinstance(value, bool):
            raise TypeError("not a boolean")
        return value


class TextParameter(Parameter):
    """A string."""

    expected = "a string"

    def _convert(self, value: Any) -> str:
        if not isinstance(value, str):
            raise TypeError("not a string")
        return value


class ChoiceParameter(Parameter):
    """One of a set of strings, e.g. ``ChoiceParameter("line", choices=("line", "circle"))``; ``choices`` may be a
    function that lists them when asked (the registered robots: :func:`bench.robot_kinds.robot_names`)."""

    def __init__(
        self, default: str, *, choices: Sequence[str] | Callable[[], Sequence[str]], description: str = ""
    ) -> None:
        self._choices = choices
        super().__init__(default, description=description)

    @property
    def choices(self) -> tuple[str, ...]:
        return tuple(self._choices() if callable(self._choices) else self._choices)

    @property
    def expected(self) -> str:
        return "one of " + ", ".join(repr(c) for c in self.choices)

    def _convert(self, value: Any) -> str:
        if value not in self.choices:
            raise ValueError("not a choice")
        return value


class PoseTableParameter(Parameter):
    """Labelled target poses, ``{label = [x_mm, y_mm, z_mm, (angles_deg...)]}``; ``None`` means "derive".

    Each pose has ``width`` numbers (5 for the pkm5: x, y, z in mm, alpha, beta in degrees; 3 for the delta).
    """

    def __init__(self, default: Any = None, *, min_width: int = 3, max_width: int = 5, description: str = "") -> None:
        self.min_width, self.max_width = min_width, max_width
        super().__init__(default, unit="mm, deg", description=description)

    @property
    def expected(self) -> str:
        return (
            f"a table of labelled poses, each [x_mm, y_mm, z_mm{', angles_deg' if self.max_width > 3 else ''}]"
            f" with {self.min_width} to {self.max_width} finite numbers"
        )

    def _convert(self, value: Any) -> dict[str, tuple[float, ...]] | None:
        if value is None:
            return None
        if not isinstance(value, dict) or not value:
            raise TypeError("not a table")
        table = {}
        for label, pose in value.items():
            if isinstance(pose, (str, bytes)) or not isinstance(pose, Sequence):
                raise TypeError("pose not a list")
            numbers = tuple(float(v) for v in pose if not isinstance(v, bool))
            if not self.min_width <= len(numbers) == len(pose) <= self.max_width:
                raise ValueError("wrong width")
            if not all(math.isfinite(n) for n in numbers):
                raise ValueError("not finite")
            table[str(label)] = numbers
        return table

    def plan_factor(self, value: Any) -> int:
        return len(value) if value else 1
