"""What page 1 needs to be signed: the measuring point statement, placeholder-free identity fields and the signature
block.

- :func:`is_placeholder`: a station template's sample text ("Operator name", "<customer>", "not recorded", "TBD")
  is not a name; a report prints such a field as an empty line to fill in by hand, never the sample text.
- :func:`measuring_point`: ISO 9283:1998 6.3 (and iso9283.md §9) requires the report to state the point measured
  (TCP / reference point): the one the caller states (``--measuring-point``), else the robot's stored ``tcp``
  setting, else what the kinematic model measures (its platform centre), said as such.
- :func:`signature_table`: tested by / approved by, each with name, signature and date lines.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import Any

from bench.reports.blocks import Table

__all__ = ["BLANK", "PLACEHOLDER_SHOWN", "SIGNATURE_ROW_MM", "is_placeholder", "measuring_point", "signature_table"]

#: A field nobody filled in: an empty line on the printed page, to be written on by hand.
BLANK = ""
#: How the settings appendix shows a stored placeholder (the value itself is never printed).
PLACEHOLDER_SHOWN = "— (template placeholder, no value stated)"
_PLACEHOLDERS = {
    "operator name",
    "customer name",
    "laboratory name",
    "lab name",
    "order number",
    "serial number",
    "not recorded",
    "not stated",
    "tbd",
    "todo",
    "n/a",
    "name",
    "xxx",
    "...",
    "-",
    "—",
}
#: Height of a signature row, mm: room for a handwritten name, signature and date (a body row of text is ~5 mm).
SIGNATURE_ROW_MM = 14.0
_TEMPLATE_MARK = re.compile(r"^\s*(<[^>]*>|\{[^}]*\}|\[[^\]]*\]|_+)\s*$")


def is_placeholder(text: Any) -> bool:
    """True when ``text`` is empty or a template's sample text rather than a value (case-insensitive)."""
    value = "" if text is None else str(text).strip()
    return not value or value.lower() in _PLACEHOLDERS or bool(_TEMPLATE_MARK.match(value))


def measuring_point(stated: str | None, robot_settings: Mapping[str, Any]) -> str:
    """The measuring point a report states: ``stated``, else ``robot_settings["tcp"]``, else the model's point."""
    for candidate in (stated, robot_settings.get("tcp")):
        if not is_placeholder(candidate):
            return str(candidate)
    return "platform centre of the kinematic model (no tool centre point stated)"


def signature_table(operator: str):
    """The signature block: who tested (the operator when named) and who approves, each to sign and date."""

    return Table(
        "signature",
        ("Role", "Name", "Signature", "Date"),
        (
            ("Tested by", BLANK if is_placeholder(operator) else operator, BLANK, BLANK),
            ("Approved by", BLANK, BLANK, BLANK),
        ),
        "Signatures",
        row_height_mm=SIGNATURE_ROW_MM,
        column_weights=(1.0, 2.0, 2.5, 1.2),
    )
