"""Acceptance criteria of every layout: ``--criterion NAME=LIMIT`` judged under the chosen decision rule.

A layout with a verdict names its characteristics (:class:`Characteristic`: what NAME means, its unit and the
figures it judges, each with its expanded U where the layout states one); :func:`judge` turns the stated limits into
a :class:`~bench.reports.content.Decision` (one verdict per figure, :func:`bench.reports.decision.decide`), which
page 1 and the decision section print the same way for every layout (:func:`decision_section`). Every limit is an
upper limit (smaller is better). A figure without a U is judged on its value under the simple rule; under the
guarded rule nothing can be proven without a U, so it is "not proven" (ISO 14253-1 needs the uncertainty).

A layout without characteristics states no verdict and says why in one line (:data:`NO_VERDICT`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from bench.errors import ConfigError
from bench.metrology.formatting import format_measured, format_value
from bench.reports.blocks import Block
from bench.reports.content import Decision
from bench.reports.decision import NOT_PROVEN, decide, rule_text, unit_of
from bench.reports.document import decision_blocks

__all__ = ["NO_VERDICT", "Characteristic", "decision_section", "judge"]

#: Why a layout states no verdict, one line each (``--criterion`` is refused with it).
NO_VERDICT = {
    "mouse_calibration": "a calibration yields a matrix and its U to put in force, not a pass/fail",
    "lasergrid_hits": "the hit rate is judged against the thesis's own specification (>= 97 % at every height)",
}

#: One figure a criterion judges: (where, value, expanded U or None when the layout states none).
Figure = tuple[str, float, float | None]


@dataclass(frozen=True)
class Characteristic:
    """What ``--criterion NAME=LIMIT`` judges in one layout."""

    description: str  #: e.g. "repeatability ±3σ̄ of every actuator"
    figures: Callable[[Any], Iterable[Figure]]  #: the report's figures it judges


def judge(
    characteristics: Mapping[str, Characteristic], report: Any, criteria: Mapping[str, float], rule: str, why: str
) -> Decision:
    """The verdicts of ``report`` against ``criteria`` (name -> upper limit) under ``rule``; ``why``: the one line a
    layout without characteristics gives for stating no verdict (refused with it)."""
    if not characteristics:
        raise ConfigError(f"--criterion {', '.join(criteria)}: this report states no verdict ({why})")
    unknown = sorted(set(criteria) - set(characteristics))
    if unknown:
        raise ConfigError(
            f"--criterion {', '.join(unknown)}: not a characteristic of this report, expected NAME=LIMIT with NAME "
            f"in {', '.join(f'{n} ({c.description})' for n, c in characteristics.items())}"
        )
    verdicts = []
    for name, limit in criteria.items():
        for where, value, u in characteristics[name].figures(report):
            if u is None and rule == "guarded":
                result = NOT_PROVEN  # no U: neither conformity nor non-conformity can be proven (ISO 14253-1)
            else:
                result = decide(value, u or 0.0, float(limit), rule)
            verdicts.append((name, where, float(value), 0.0 if u is None else float(u), float(limit), result))
    return Decision(rule_text(rule), tuple(verdicts))


def decision_section(report: Any, no_criterion: str) -> tuple[Block, ...]:
    """The decision section of any layout: the rule and one row per verdict, or ``no_criterion`` without any."""
    decision = getattr(report, "decision", None)
    if decision is None or not decision.verdicts:
        return decision_blocks(no_criterion if decision is None else decision.rule)
    return decision_blocks(
        decision.rule,
        ("Project criterion", "Where", "Value ± U", "Limit", "Result"),
        [
            (
                f"{name} (project criterion)",
                where,
                format_measured(value, u) if u else f"{format_value(value, None)} (U not stated)",
                f"{limit:g} {unit_of(name)}".strip(),
                result,
            )
            for name, where, value, u, limit, result in decision.verdicts
        ],
    )
