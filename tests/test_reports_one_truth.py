"""One truth across formats: the HTML and the PDF are rendered from one document and state the same verdicts and
figures; every ``value ± U`` printed in any table of a report is rounded by its U (GUM 7.2.6), checked by walking
every cell, independently of bench's formatter."""

from __future__ import annotations

import re

import pytest
from reports_runs import SETTINGS, html_tables, pdf_text, pose_config, write_pose_run

from bench.reports import write_report
from bench.store import Store

MEASURED = re.compile(r"([+-]?\d+(?:\.(\d+))?) ± (\d+(?:\.(\d+))?)")


@pytest.fixture(scope="module")
def judged(tmp_path_factory):
    folder = tmp_path_factory.mktemp("truth")
    with Store(folder / "bench.db") as store:
        run_id = write_pose_run(
            store,
            seed=5,
            bias_mm=(0.3, -0.2, 0.1),
            noise_mm=0.04,
            config=pose_config(velocities_pct=[100.0]),
            settings={**SETTINGS},
        )
        yield write_report(
            store, run_id, folder / "out", criteria={"AP_mm": 0.4, "RP_mm": 0.2}, decision_rule="guarded"
        )


def _two_significant_digits(u_text: str) -> bool:
    digits = u_text.replace(".", "").lstrip("0")
    return 1 <= len(digits) <= 2


def test_every_value_with_u_is_rounded_by_its_u(judged):
    checked = 0
    for ident, rows in html_tables(judged.html).items():
        for row in rows[1:]:
            for cell in row:
                for _value, value_decimals, u, u_decimals in MEASURED.findall(cell):
                    assert len(value_decimals) == len(u_decimals), (ident, cell)
                    assert _two_significant_digits(u), (ident, cell)
                    checked += 1
    assert checked >= 20  # the results, headline, verdict and decision tables were walked


def test_html_and_pdf_state_the_same_verdicts_and_figures(judged):
    tables = html_tables(judged.html)
    pdf = pdf_text(judged.pdf)
    squashed = pdf.replace(" ", "")
    for ident in ("summary-identity", "headline", "verdict", "decision", "results"):
        for row in tables[ident][1:]:
            for cell in row:
                if cell:  # table cells may wrap in the PDF: compared without spaces
                    assert cell.replace(" ", "") in squashed, (ident, cell)
    results = [row[-1] for row in tables["decision"][1:]]
    assert set(results) <= {"pass", "not proven", "fail"}
    for word in set(results):
        assert pdf.count(word) >= 1
    assert judged.report_id in pdf and judged.report_id in judged.html.read_text(encoding="utf-8")
