"""The decision rule of a report's verdict: the customer chooses it, the report names it and shows its zones.

- ``simple``: simple acceptance (ILAC-G8:09/2019 4.2.1, shared risk): pass when the measured value <= the limit;
  the expanded uncertainty U is reported but not used.
- ``guarded``: guarded acceptance (ISO 14253-1:2017 conformity zone reduced by U; ILAC-G8 4.2.2 with a guard band
  w = U): pass when value + U <= limit (conformity proven), fail when value − U > limit (non-conformity proven),
  otherwise "not proven" (the uncertainty range straddles the limit, neither can be stated).

Every limit here is an upper limit (AP, RP and the like: smaller is better).

Examples
--------
>>> decide(2.68, 0.64, 3.0, "simple")
'pass'
>>> decide(2.68, 0.64, 3.0, "guarded")
'not proven'
>>> decide(3.70, 0.64, 3.0, "guarded")
'fail'
"""

from __future__ import annotations

__all__ = ["DECISION_RULES", "FAIL", "NOT_PROVEN", "PASS", "decide", "overall", "rule_text", "unit_of"]

PASS, NOT_PROVEN, FAIL = "pass", "not proven", "fail"
#: The rules ``bench report --decision-rule`` offers; the first is the default.
DECISION_RULES = ("simple", "guarded")

_RULE_TEXT = {
    "simple": "simple acceptance (ILAC-G8:09/2019 4.2.1): pass when the measured value <= the project criterion; "
    "the expanded uncertainty U is reported but not used as a guard band",
    "guarded": "guarded acceptance (ISO 14253-1:2017, guard band w = U, ILAC-G8:09/2019 4.2.2): zones pass "
    "(value + U <= limit), not proven (value − U <= limit < value + U), fail (value − U > limit)",
}


def _check(rule: str) -> None:
    if rule not in DECISION_RULES:
        from bench.errors import ConfigError

        raise ConfigError(f"--decision-rule {rule}: expected one of {', '.join(DECISION_RULES)}")


def decide(value: float, expanded_u: float, limit: float, rule: str = "simple") -> str:
    """The zone of ``value`` ± ``expanded_u`` against the upper ``limit`` under ``rule`` (module docstring).

    Simple: pass if x <= L else fail. Guarded (ISO 14253-1): pass if x + U <= L, fail if x − U > L, otherwise
    not proven.
    """
    _check(rule)
    if rule == "simple":
        return PASS if value <= limit else FAIL
    if value + abs(expanded_u) <= limit:
        return PASS
    return FAIL if value - abs(expanded_u) > limit else NOT_PROVEN


def overall(results) -> str:
    """The result of a set of verdicts: fail when any fails, not proven when any is not proven, else pass."""
    results = list(results)
    return FAIL if FAIL in results else NOT_PROVEN if NOT_PROVEN in results else PASS


def rule_text(rule: str) -> str:
    """The sentence that names ``rule`` in a report."""
    _check(rule)
    return _RULE_TEXT[rule]


def unit_of(name: str) -> str:
    """The unit a criterion's name ends with: ``AP_mm`` -> mm, ``t_s`` -> s, ``rate_pct`` -> %."""
    return {"mm": "mm", "s": "s", "pct": "%"}.get(name.rsplit("_", 1)[-1], "")
