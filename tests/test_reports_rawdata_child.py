"""A long run's raw-data CSV written by a second process (bench.reports.rawdata_child): byte for byte the serial
writer's on a real simulated path run and through ``write_report`` (the SHA-256 the report cites), the store's own
fallback taken in the child too, and a failing or disagreeing child is one line with nothing written where the
report would cite it."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest
from reports_runs import simulated_path_run
from test_reports_rawdata_text import _path_store, _samples

from bench.errors import BenchError
from bench.reports import rawdata_child, write_report
from bench.reports.rawdata import StreamedSeries, write_table_csv
from bench.reports.rawdata_child import CsvInChild, long_enough, worth_a_process
from bench.store import Store
from bench.store.export import series_table


@pytest.fixture(scope="module")
def path_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("child")
    return folder, simulated_path_run(folder, shape="both", cycles=2, seed=6)


def _written(store: Store, run_id: int, path, *, in_child: bool) -> tuple[str, int, bytes, int | None]:
    raw = StreamedSeries(store, run_id, "path", rows=700, in_child=in_child)
    assert (raw.child is not None) == in_child
    for _ in raw.passing_stored(store.iter_samples_text(run_id, kind="path")):
        pass
    digest, rows = raw.write_csv(path)
    assert raw.child is None or not Path(raw.child.folder).exists()  # moved into place, nothing left behind
    return digest, rows, path.read_bytes(), raw.passed


def test_the_childs_csv_is_the_serial_writers_byte_for_byte(path_run):
    folder, run_id = path_run
    with Store(folder / "p.db", read_only=True) as store:
        serial = _written(store, run_id, folder / "serial.csv", in_child=False)
        child = _written(store, run_id, folder / "child.csv", in_child=True)
        whole = write_table_csv(series_table(store, run_id, kind="path"), folder / "whole.csv")
        samples = store.sample_kinds(run_id)["path"]
    assert child[:3] == serial[:3] and child[3] == samples
    assert (folder / "child.csv").stat().st_mode == (folder / "serial.csv").stat().st_mode  # readable alike
    assert child[0] == whole == hashlib.sha256(child[2]).hexdigest()
    assert child[2] == (folder / "whole.csv").read_bytes() and child[1] > 1000


def test_a_sample_the_child_cannot_take_as_text_is_written_from_the_store_there_too(tmp_path):
    samples = _samples(np.random.default_rng(4), [5, 6, 7])
    samples[1][3]["t_s"][2] = 2  # an integer: pandas writes 2.0, the stored text says 2
    store, run_id = _path_store(tmp_path, samples)
    with store:
        expected = write_table_csv(series_table(store, run_id, kind="path"), tmp_path / "whole.csv")
        digest, rows, written, passed = _written(store, run_id, tmp_path / "child.csv", in_child=True)
    assert (digest, rows, passed) == (expected, 18, 3)
    assert written == (tmp_path / "whole.csv").read_bytes() and b",2.0\n" in written


def test_the_report_cites_the_same_csv_whichever_process_writes_it(path_run, monkeypatch):
    folder, run_id = path_run
    serial = write_report(folder / "p.db", run_id, folder / "serial", ["html"])
    monkeypatch.setattr(rawdata_child, "PROCESS_MIN_SAMPLES", 1)
    monkeypatch.setattr(rawdata_child, "core_time_free", lambda: True)  # whatever the load of the machine now
    joined = []
    monkeypatch.setattr(
        CsvInChild, "join", lambda self, *args, join=CsvInChild.join: joined.append(self) or join(self, *args)
    )
    child = write_report(folder / "p.db", run_id, folder / "child", ["html"])
    assert len(joined) == 1
    assert child.csv[0].read_bytes() == serial.csv[0].read_bytes()
    digest = hashlib.sha256(child.csv[0].read_bytes()).hexdigest()
    assert digest in child.html.read_text() and digest in serial.html.read_text()


def test_a_failing_child_is_one_line_and_leaves_no_csv(tmp_path):
    not_a_store = tmp_path / "notes.db"
    not_a_store.write_text("not a store\n")
    child = CsvInChild(str(not_a_store), 7, "path", 100)
    with pytest.raises(BenchError) as raised:
        child.join(tmp_path / "run7_samples.csv", 10)
    message = str(raised.value)
    assert message.startswith("run 7: the raw-data CSV was not written (") and "\n" not in message
    assert "notes.db" in message and "Traceback" not in message
    assert not (tmp_path / "run7_samples.csv").exists() and not Path(child.folder).exists()


def test_a_child_that_read_another_number_of_samples_is_refused(path_run):
    folder, run_id = path_run
    with Store(folder / "p.db", read_only=True) as store:
        samples = store.sample_kinds(run_id)["path"]
        child = CsvInChild(store.path, run_id, "path", 700)
    with pytest.raises(BenchError, match=f"it read {samples} samples and the analysis {samples - 1}: the run changed"):
        child.join(folder / "refused.csv", samples - 1)
    assert not (folder / "refused.csv").exists() and not Path(child.folder).exists()


def test_a_process_only_from_the_stated_number_of_samples_of_a_store_file_with_core_time_free(path_run, monkeypatch):
    folder, run_id = path_run
    monkeypatch.setattr(rawdata_child, "core_time_free", lambda: True)
    with Store(folder / "p.db", read_only=True) as store:
        samples = store.sample_kinds(run_id)["path"]
        assert not long_enough(store, run_id, "path") and samples < 1000  # a short run: below the stated 1,000
        monkeypatch.setattr(rawdata_child, "PROCESS_MIN_SAMPLES", samples)
        assert long_enough(store, run_id, "path") and worth_a_process(store, run_id, "path")
        monkeypatch.setattr(rawdata_child, "core_time_free", lambda: False)  # a busy machine: the serial path
        assert not worth_a_process(store, run_id, "path")
        assert StreamedSeries(store, run_id, "path").child is None
        monkeypatch.setattr(rawdata_child, "PROCESS_MIN_SAMPLES", samples + 1)
        assert not long_enough(store, run_id, "path")
    with Store(":memory:") as memory:
        assert not long_enough(memory, 1, "path")
