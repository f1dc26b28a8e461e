"""The nominal mouse calibration of a cpi is stored once (issue 32 follow-up): a run with the nominal cpi after a
measured calibration was stored reuses the nominal record instead of writing a new version, which would be newer
than the measured one."""

from __future__ import annotations

import pytest

from bench.rigs.mice_station import mouse_calibration
from bench.sensors.calibration import MM_PER_INCH
from bench.store import Store

MEASURED = {"x_mm_per_count": 0.0311, "u_x_mm_per_count": 2e-5, "y_mm_per_count": 0.0324, "mm_per_count": 0.03175}


def test_a_nominal_run_after_a_measured_calibration_reuses_the_nominal_record(tmp_path):
    with Store(tmp_path / "bench.db") as store:
        first, _ = mouse_calibration(store, 800.0, source="bench.toml")
        measured = store.add_calibration("mouse", MEASURED)
        again, calibration = mouse_calibration(store, 800.0, source="bench.toml")
        third, _ = mouse_calibration(store, 800.0, source="bench.toml")
        versions = [c.version for c in store.calibrations() if c.name == "mouse"]
        newest = store.calibration("mouse")
    assert (first.version, measured.version) == (1, 2)
    assert again.id == first.id and third.id == first.id
    assert versions == [1, 2]
    assert newest.id == measured.id  # the newest mouse calibration stays the measured one
    assert calibration.calibration_id == "mouse-v1"
    assert calibration.counts_to_mm([800, 800]) == pytest.approx([25.4, 25.4])


def test_another_cpi_is_its_own_nominal_record(tmp_path):
    with Store(tmp_path / "bench.db") as store:
        at_800, _ = mouse_calibration(store, 800.0)
        at_1600, _ = mouse_calibration(store, 1600.0)
        back, _ = mouse_calibration(store, 800.0)
    assert at_1600.version == 2 and at_1600.params["mm_per_count"] == pytest.approx(MM_PER_INCH / 1600)
    assert back.id == at_800.id
