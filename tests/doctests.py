"""Running a module's docstring examples (its Examples sections) as tests, so the documented numbers stay true."""

from __future__ import annotations

import doctest
import linecache
from types import ModuleType


def run_doctests(module: ModuleType) -> doctest.TestResults:
    """``doctest.testmod(module)`` with whitespace normalised; (failed, attempted).

    The line cache is emptied first: doctest's runner checks every file in it against the disk before each
    docstring (``Pdb.reset`` -> ``linecache.checkcache``), and in a test process that has imported PySide6, whose
    import hook reads the source of every module imported after it, that is thousands of ``stat`` calls a docstring
    (7 s of the suite's CPU). The cache only saves re-reading files; emptying it changes no result."""
    linecache.clearcache()
    return doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
