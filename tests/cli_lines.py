"""What a command printed on stderr, read as the one line a user error must be."""

from __future__ import annotations

from typing import Any


def one_error_line(capsys: Any) -> str:
    """The single line on stderr since the last read (no traceback, nothing else), which a refusal must be."""
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in captured.err, captured.err
    return lines[0]
