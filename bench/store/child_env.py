"""The environment of a ``python -m bench...`` child process that reads a store file beside its parent (the lab
sync's producers, :mod:`bench.store.lab_batches`; a long report's raw-data CSV writer,
:mod:`bench.reports.rawdata_child`)."""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["bench_child_env"]

#: The folder holding bench/, wherever this copy of bench came from (a checkout, a wheel, a test's tree).
_PACKAGE_ROOT = str(Path(__file__).resolve().parents[2])


def bench_child_env() -> dict[str, str]:
    """This process's environment with the folder holding this bench first on ``PYTHONPATH``, so that the child
    runs this very copy of bench (not another one installed elsewhere)."""
    return {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [_PACKAGE_ROOT, os.environ.get("PYTHONPATH")])),
    }
