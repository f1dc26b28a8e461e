"""The protocol base class: typed parameters, TOML loading that refuses unknown keys, and the protocol registry.

A protocol is data (a TOML file naming ``protocol = "<name>"`` and its parameter values) plus a Python class
whose :meth:`Protocol.steps` generator turns the parameters into steps. Generators are deterministic given the
parameters, so a run can be regenerated from its stored configuration to resume it or to re-analyse it.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar

from bench.errors import ConfigError
from bench.protocols.kinematics import DEFAULT_SINGULARITY_THRESHOLD, robot_model
from bench.protocols.parameters import MAX_PLAN_REPEATS, ChoiceParameter, FloatParameter, Parameter
from bench.robot_kinds import robot_names
from bench.steps import Move, Plan

__all__ = ["PROTOCOLS", "Protocol", "load_protocol", "protocol_from_config", "register"]

#: Protocol classes by name, filled by :func:`register`.
PROTOCOLS: dict[str, type[Protocol]] = {}


def register(cls: type[Protocol]) -> type[Protocol]:
    """Class decorator: make a protocol loadable by its ``name``."""
    PROTOCOLS[cls.name] = cls
    return cls


class Protocol:
    """Base of all test protocols (a PyMeasure ``Procedure`` whose ``execute`` is a bluesky-style plan).

    Subclasses set ``name``, ``version``, ``robots`` (the robots it is written for) and ``title``, declare
    parameters as class attributes, and implement :meth:`steps`. :meth:`final_steps` (default: nothing) is the
    clean-up plan that the runner runs after completion, stop or abort (not after halt).
    """

    name: ClassVar[str] = "base"
    version: ClassVar[str] = "0"
    title: ClassVar[str] = ""
    #: the robots it is written for; None: every robot of the registry (bench.robot_kinds)
    robots: ClassVar[tuple[str, ...] | None] = None
    #: Keys :meth:`config` adds that state the protocol's fixed design for the report (not parameters): a stored
    #: run's configuration carries them, and rebuilding the protocol from it (a resume) leaves them out.
    design_keys: ClassVar[tuple[str, ...]] = ()

    robot = ChoiceParameter("pkm5", choices=robot_names, description="robot the protocol drives")
    min_inverse_condition = FloatParameter(
        DEFAULT_SINGULARITY_THRESHOLD,
        minimum=0.0,
        maximum=1.0,
        description="pre-flight refuses targets whose Jacobian inverse condition "
        "number is below this (singularity proximity)",
    )

    def __init__(self, source: str = "parameters", **values: Any) -> None:
        self.source = source
        known = self.parameters()
        for key, value in values.items():
            if key not in known:
                raise ConfigError(f"{source}: unknown key {key!r}, expected one of {', '.join(sorted(known))}")
            setattr(self, key, value)
        if self.robots is not None and self.robot not in self.robots:
            raise ConfigError(
                f"{source}: robot = {self.robot!r}, expected one of {', '.join(self.robots)} for protocol {self.name!r}"
            )
        self.refuse_absurd_plan()
        self.validate()

    def refuse_absurd_plan(self) -> None:
        """One line, before any plan is built, when the product of the protocol's sizes (counts, lists, pose
        tables) exceeds :data:`MAX_PLAN_REPEATS`: each size is bounded alone, their product would not be."""
        factors = {key: p.plan_factor(getattr(self, key)) for key, p in self.parameters().items()}
        sizes = {key: factor for key, factor in factors.items() if factor > 1}
        repeats = math.prod(sizes.values())
        if repeats > MAX_PLAN_REPEATS:
            product = " x ".join(f"{key} {factor:,}" for key, factor in sizes.items())
            raise ConfigError(
                f"{self.source}: a plan of {product} = {repeats:,} repetitions, expected at most "
                f"{MAX_PLAN_REPEATS:,} (lower one of them)"
            )

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.resolved().items())
        return f"{type(self).__name__}({args})"

    @classmethod
    def parameters(cls) -> dict[str, Parameter]:
        """The declared parameters by name, base class first."""
        found: dict[str, Parameter] = {}
        for klass in reversed(cls.__mro__):
            found.update({k: v for k, v in vars(klass).items() if isinstance(v, Parameter)})
        return found

    def resolved(self) -> dict[str, Any]:
        """Every parameter value (defaults included) as plain JSON-ready data, stored with the run."""
        out = {}
        for key in self.parameters():
            value = getattr(self, key)
            if isinstance(value, tuple):
                value = list(value)
            elif isinstance(value, dict):
                value = {k: list(v) for k, v in value.items()}
            out[key] = value
        return out

    def config(self) -> dict[str, Any]:
        """The self-describing configuration: protocol name and version plus the resolved parameters."""
        return {"protocol": self.name, "protocol_version": self.version, **self.resolved()}

    def validate(self) -> None:
        """Cross-parameter checks; raise ``ConfigError`` naming ``self.source``. Default: none."""

    def limit_warnings(self) -> tuple[str, ...]:
        """One line per setting that goes beyond a documented failure or limit of the robot (printed by the dry
        run before anything moves). Default: none."""
        return ()

    def steps(self) -> Plan:
        """The step generator of the protocol."""
        raise NotImplementedError

    def final_steps(self) -> Plan:
        """Clean-up steps after the run (e.g. :meth:`return_home`); default: none."""
        return
        yield

    def return_home(self) -> Plan:
        """The usual clean-up: back to the robot's home at full speed."""
        yield Move(tuple(robot_model(self.robot).home), 100.0, "home")

    def on_completed(self, store: Any, run_id: int) -> None:
        """Called once the run has completed (e.g. to store a fitted calibration); default: nothing."""


def protocol_from_config(config: Mapping[str, Any], source: str = "parameters", *, stored: bool = False) -> Protocol:
    """Build a protocol from a mapping with a ``protocol`` key (a TOML document or, ``stored``, a stored run's
    config, whose design keys are left out; in a TOML file they are unknown keys like any other)."""
    values = dict(config)
    name = values.pop("protocol", None)
    values.pop("protocol_version", None)
    if name is None:
        raise ConfigError(f"{source}: missing key 'protocol', expected one of {', '.join(sorted(PROTOCOLS))}")
    if not isinstance(name, str) or name not in PROTOCOLS:  # (a list or a table is no name either)
        raise ConfigError(f"{source}: protocol = {name!r}, expected one of {', '.join(sorted(PROTOCOLS))}")
    if stored:
        for key in PROTOCOLS[name].design_keys:
            values.pop(key, None)
    return PROTOCOLS[name](source=source, **values)


def load_protocol(path: str | Path, **overrides: Any) -> Protocol:
    """Read a protocol TOML file; ``overrides`` (e.g. ``robot`` from the command line) win over the file."""
    path = Path(path)
    try:
        document = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError as exc:
        raise ConfigError(f"{path}: no such protocol file") from exc
    except IsADirectoryError:
        raise ConfigError(f"{path}: a folder, expected a protocol file (examples/*.toml)") from None
    except UnicodeDecodeError:
        raise ConfigError(f"{path}: not a text file, expected a protocol TOML file") from None
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read it ({exc.strerror or exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path.name}: not valid TOML ({exc})") from exc
    document.update({k: v for k, v in overrides.items() if v is not None})
    return protocol_from_config(document, source=path.name)
