"""The budget table's registration rows (the registration at home and the accuracy term it makes with the reading)
appear only on a report that states an accuracy U (AP, AT_p) (issue 32 follow-up): a stabilisation or
positioning-time report of a run with registrations states no such U, so it names neither row; a path report does.
"""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path

import pytest

from bench.cli import main
from bench.reports.document import _instruments
from bench.reports.path import collect_path
from bench.reports.positioning_time import collect_positioning_time
from bench.reports.stabilisation import collect_stabilisation
from bench.store import Store
from bench.store.record_checksum import seal_run

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
REGISTRATION = "registration at home (the run's largest)"
ACCURACY_TERM = "accuracy term (AP, AT_p), per axis"


def _run_with_registration(folder: Path, protocol: str) -> Path:
    """A simulated run of ``protocol`` whose stored settings carry a registration at home, as a mice station's do."""
    store = folder / "bench.db"
    assert main(["run", str(EXAMPLES / protocol), "--sim", "--store", str(store), "--no-progress"]) == 0
    db = sqlite3.connect(store)
    try:
        settings = json.loads(db.execute("SELECT settings_json FROM runs WHERE id = 1").fetchone()[0])
        settings["registrations"] = [{"segment": 1, "u_mm": 0.3817, "utc": "2026-01-01T00:00:00+00:00"}]
        db.execute("UPDATE runs SET settings_json = ? WHERE id = 1", (json.dumps(settings),))
        seal_run(db, 1)  # an edit by hand, sealed as bench seals its own
        db.commit()
    finally:
        db.close()
    return store


def _budget_names(report) -> list[str]:
    (budget,) = [b for b in _instruments(report).blocks if getattr(b, "ident", "") == "budget"]
    return [row[0] for row in budget.rows]


@pytest.mark.parametrize(
    "protocol, collect",
    [
        ("iso9283_stabilisation.toml", collect_stabilisation),
        ("iso9283_positioning_time.toml", collect_positioning_time),
    ],
)
def test_a_report_stating_no_accuracy_u_names_no_registration_rows(tmp_path, protocol, collect):
    store = _run_with_registration(tmp_path, protocol)
    with Store(store, read_only=True) as opened:
        names = _budget_names(collect(opened, 1))
    assert names  # the instrument's own terms are still there
    assert REGISTRATION not in names and ACCURACY_TERM not in names


def test_a_path_report_names_both(tmp_path):
    store = _run_with_registration(tmp_path, "iso9283_path_quick.toml")
    with Store(store, read_only=True) as opened:
        names = _budget_names(collect_path(opened, 1))
    assert REGISTRATION in names and ACCURACY_TERM in names
