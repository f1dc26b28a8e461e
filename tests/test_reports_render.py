"""The rendered report: PDF pages and text (pypdf), self-contained HTML, headless Chromium, comparison, CLI."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
from reports_runs import write_pose_run

from bench.cli import main
from bench.reports import write_comparison, write_report
from bench.store import Store

CHROMIUM = Path("/usr/bin/chromium")
TITLE = "ISO 9283-style pose accuracy and repeatability"


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    folder = tmp_path_factory.mktemp("render")
    with Store(folder / "bench.db") as store:
        before = write_pose_run(store, seed=2, bias_mm=(0.4, 0.0, -0.2))
        after = write_pose_run(store, seed=3, bias_mm=(0.05, 0.0, 0.0), calibration=False)
        single = write_report(store, before, folder / "out", criteria={"AP_mm": 0.3})
        compared = write_comparison(store, before, after, folder / "out")
    return folder, before, after, single, compared


def _pdf_text(path):
    from pypdf import PdfReader

    reader = PdfReader(path)
    return reader, [page.extract_text() for page in reader.pages]


def test_pdf_has_every_section_on_numbered_pages(reports):
    _, before, _, single, _ = reports
    reader, pages = _pdf_text(single.pdf)
    assert 4 <= len(pages) <= 10
    text = " ".join(pages)
    assert TITLE in pages[0] and f"(stored run {before})" in pages[0]
    for heading in (
        "1. Identification",
        "3. Method",
        "Deviations from ISO 9283",
        "5. Instruments",
        "6. Results",
        "7. Plots",
        "8. Decision",
        "9. Raw data",
        "10. Statement of scope",
    ):
        assert heading in text, heading
    assert all(f"page {i + 1} of {len(pages)}" in page for i, page in enumerate(pages))
    assert reader.metadata.title == TITLE
    assert "AP_mm (project criterion)" in text and "ISO 9283 certified" not in text


def test_html_is_self_contained_with_inline_plots(reports):
    _, _, _, single, _ = reports
    html = single.html.read_text(encoding="utf-8")
    assert not re.search(r"<(script|link|iframe)\b", html)
    assert not re.search(r"(src|href)=\"(https?:|file:|//)", html)
    assert all(src.startswith("data:image/png;base64,") for src in re.findall(r'<img src="([^"]*)"', html))
    assert html.count('<img src="data:image/png;base64,') >= 3  # pose scatter, workspace with AP vectors, drift series
    for ident in ("identification", "deviations", "instrument", "budget", "results", "decision", "rawdata"):
        assert f'<table id="{ident}">' in html


def test_same_tables_in_html_and_pdf(reports):
    _, _, _, single, _ = reports
    html = single.html.read_text(encoding="utf-8")
    _, pages = _pdf_text(single.pdf)
    text = " ".join(pages)
    for cell in re.findall(r"<td[^>]*>([^<]{6,40})</td>", html)[:60]:
        assert cell.split()[0] in text, cell


@pytest.mark.skipif(
    not CHROMIUM.exists(),
    reason="Debian chromium not installed (/usr/bin/chromium); .ci/run installs it when apt is available",
)
def test_html_renders_in_headless_chromium(reports, tmp_path):
    _, before, _, single, _ = reports
    args = [
        str(CHROMIUM),
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        f"--user-data-dir={tmp_path / 'profile'}",
        "--window-size=1280,1600",
    ]
    shot = tmp_path / "report.png"
    subprocess.run([*args, f"--screenshot={shot}", single.html.as_uri()], capture_output=True, timeout=120, check=True)
    dom = subprocess.run(
        [*args, "--dump-dom", single.html.as_uri()], capture_output=True, text=True, timeout=120, check=True
    ).stdout
    from PIL import Image

    pixels = np.asarray(Image.open(shot).convert("L"), dtype=float)
    assert pixels.shape == (1600, 1280)
    assert pixels.std() > 10 and (pixels < 128).mean() > 0.005  # text and rules drawn, not a blank page
    assert f"<title>{TITLE}</title>" in dom and f"(stored run {before})" in dom
    results = re.search(r'<table id="results">(.*?)</table>', dom, re.DOTALL).group(1)
    assert [re.sub("<.*?>", "", c) for c in re.findall(r"<tr><td>(P\d)</td>", results)] == [
        "P1",
        "P2",
        "P3",
        "P4",
        "P5",
    ]


def test_comparison_pairs_the_poses_of_both_runs(reports):
    _, before, after, _, compared = reports
    html = compared.html.read_text(encoding="utf-8")
    assert f"Comparison of run {before} (A) and run {after} (B)" in html
    assert len(compared.csv) == 2
    results = re.search(r'<table id="results">(.*?)</table>', html, re.DOTALL).group(1)
    rows = re.findall(r"<tr>(.*?)</tr>", results, re.DOTALL)[1:]
    assert len(rows) == 5
    for row in rows:
        cells = re.findall(r"<td[^>]*>(.*?)</td>", row)
        ap_a, ap_b, delta = float(cells[1].split()[0]), float(cells[2].split()[0]), float(cells[3])
        places = len(cells[3].split(".")[-1])  # the difference is rounded like the values
        assert delta == pytest.approx(ap_b - ap_a, abs=1.5 * 10**-places)
        assert ap_a > ap_b  # the "before" run has the larger bias
    _, pages = _pdf_text(compared.pdf)
    assert "Conditions that differ" in " ".join(pages)


def test_cli_report_writes_and_prints_the_paths(reports, capsys, tmp_path):
    folder, before, _, _, _ = reports
    assert (
        main(
            [
                "report",
                str(before),
                "--store",
                str(folder / "bench.db"),
                "--out",
                str(tmp_path),
                "--format",
                "html",
                "--criterion",
                "RP_mm=0.5",
            ]
        )
        == 0
    )
    printed = capsys.readouterr().out.split()
    assert printed == [str(tmp_path / f"report_run{before}.html"), str(tmp_path / f"run{before}_samples.csv")]
    assert "RP_mm (project criterion)" in Path(printed[0]).read_text(encoding="utf-8")


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["report", "99"], "run 99: no such run"),
        (["report", "1", "--criterion", "grade=1"], "--criterion grade=1: unknown name 'grade'"),
        (["report", "1", "--criterion", "AP_mm=small"], "--criterion AP_mm=small: 'small' is not a number of mm"),
    ],
)
def test_cli_errors_are_one_line_with_exit_2(reports, capsys, argv, message):
    folder = reports[0]
    assert main([*argv, "--store", str(folder / "bench.db"), "--out", str(folder / "cli")]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_cli_refuses_a_missing_store(tmp_path, capsys):
    assert main(["report", "1", "--store", str(tmp_path / "none.db"), "--out", str(tmp_path)]) == 2
    assert "none.db: no run store there" in capsys.readouterr().err


def test_pdf_figures_are_the_html_figures_pixel_for_pixel(reports):
    """The PDF embeds the PNGs' deflated rows as they are (bench.reports.pdf): decoded by pypdf (Flate with PNG
    predictors) they are the pixels Pillow decodes from the HTML's PNGs, figure by figure."""
    import base64
    import io

    from PIL import Image
    from pypdf import PdfReader

    _, _, _, single, _ = reports
    html = single.html.read_text(encoding="utf-8")
    inline = [
        np.asarray(Image.open(io.BytesIO(base64.b64decode(data))).convert("RGB"))
        for data in re.findall(r'<img src="data:image/png;base64,([^"]*)"', html)
    ]
    embedded = [np.asarray(image.image.convert("RGB")) for page in PdfReader(single.pdf).pages for image in page.images]
    assert len(embedded) == len(inline) >= 3
    for pdf, png in zip(embedded, inline):
        np.testing.assert_array_equal(pdf, png)
