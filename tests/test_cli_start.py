"""``bench`` starts cheaply: building the whole parser imports no numeric, plotting or table library.

Each check runs in a fresh interpreter (a subprocess), since this test process has long imported everything.
"""

import contextlib
import io
import json
import subprocess
import sys

import pytest

HEAVY = ("scipy", "matplotlib", "pandas", "numpy", "PySide6", "reportlab", "serial")


def imported_after(code: str) -> dict:
    """Run ``code`` in a fresh interpreter; the heavy top-level packages it left in ``sys.modules``, and its output."""
    probe = (
        f"import sys\n{code}\n"
        f"print(json.dumps(sorted({{m.split('.')[0] for m in sys.modules}} & set({list(HEAVY)!r}))))"
    )
    proc = subprocess.run([sys.executable, "-c", "import json\n" + probe], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return {"heavy": json.loads(proc.stdout.splitlines()[-1]), "stdout": proc.stdout}


def test_building_the_whole_parser_imports_no_heavy_package():
    result = imported_after("import bench.cli\nbench.cli.build_parser()")
    assert result["heavy"] == []


def test_building_the_whole_parser_opens_no_store_module():
    """The parser's defaults that live in the store (``bench sync --batch``) are deferred to their sub-command."""
    result = imported_after(
        "import bench.cli\nbench.cli.build_parser()\n"
        "print(sorted(m for m in ('bench.store', 'msgspec', 'sqlite3') if m in sys.modules))"
    )
    assert "[]" in result["stdout"].splitlines()[-2], result["stdout"]


def test_sync_help_shows_the_stores_batch_default(capsys):
    import bench.cli
    from bench.store.lab_batches import BATCH_SAMPLES

    with pytest.raises(SystemExit):
        bench.cli.main(["sync", "--help"])
    assert f"samples per transaction (default: {BATCH_SAMPLES})" in " ".join(capsys.readouterr().out.split())


def test_top_level_help_and_version_import_no_heavy_package():
    help_text = imported_after(
        "import contextlib, io\nimport bench.cli\nout = io.StringIO()\n"
        "with contextlib.redirect_stdout(out), contextlib.suppress(SystemExit):\n"
        "    bench.cli.main(['--help'])\n"
        "print(repr('kin' in out.getvalue() and 'analyze' in out.getvalue()))"
    )
    assert help_text["heavy"] == [] and "True" in help_text["stdout"]
    version = imported_after(
        "import contextlib, io\nimport bench.cli\nout = io.StringIO()\n"
        "with contextlib.redirect_stdout(out), contextlib.suppress(SystemExit):\n"
        "    bench.cli.main(['--version'])\n"
        "print(repr(out.getvalue()))"
    )
    assert version["heavy"] == [] and "'bench " in version["stdout"]


def test_inverse_kinematics_imports_numpy_only():
    result = imported_after(
        "import contextlib, io\nimport bench.cli\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    code = bench.cli.main(['kin', 'ik', 'pkm5', '111.31', '-20', '310', '--json'])\n"
        "assert code == 0, code"
    )
    assert result["heavy"] == ["numpy"]


@pytest.mark.parametrize(
    ("argv", "option", "choices"),
    [
        (["kin", "fk", "pkm5"], "--mode", ["auto", "translation", "alpha", "beta"]),
        (["analyze", "actuator"], "--robot", ["pkm5"]),
        (["export"], "--format", ["csv", "parquet"]),
        (["report"], "--format", ["html", "pdf", "all"]),
    ],
)
def test_deferred_arguments_appear_when_their_command_is_parsed(argv, option, choices):
    from bench.cli import build_parser

    parser = build_parser()
    group = parser._subparsers._group_actions[0].choices[argv[0]]
    for name in argv[1:]:
        group = group._subparsers._group_actions[0].choices[name]
    assert option not in group._option_string_actions  # not added yet: building the parser imported nothing
    group.fill()
    assert list(group._option_string_actions[option].choices) == choices


def test_a_deferred_choice_is_checked_like_any_other(capsys):
    from bench.cli import main

    with pytest.raises(SystemExit) as exit_:
        main(["kin", "fk", "pkm5", "184", "184", "184", "184", "192", "192", "--mode", "gamma"])
    assert exit_.value.code == 2
    assert "argument --mode: invalid choice: 'gamma'" in capsys.readouterr().err


def test_simulator_help_lists_its_own_options(capsys):
    from bench.cli import main

    with pytest.raises(SystemExit) as exit_:
        main(["sim", "pkm5", "--help"])
    out = capsys.readouterr().out
    assert exit_.value.code == 0
    assert "Simulated 5-DOF PKM controller on a pseudo-terminal" in out and "--speed-factor" in out


def test_the_desktop_app_and_the_runner_import_no_table_plotting_or_scipy_package():
    """The main window appears before pandas and matplotlib are loaded (the live view imports them off the GUI
    thread); the metrology package resolves its names on first use, so a constant costs no pandas."""
    for module in ("bench.gui.app", "bench.protocols", "bench.metrology.documents", "bench.store"):
        heavy = imported_after(f"import {module}")["heavy"]
        assert not {"pandas", "matplotlib", "scipy"} & set(heavy), (module, heavy)


def test_the_metrology_package_still_offers_every_name():
    result = imported_after(
        "import bench.metrology as m\nfrom bench.metrology import pose_accuracy, "
        "analyze_actuators\nprint(len(m.__all__), all(hasattr(m, n) for n in m.__all__))"
    )
    count, every = result["stdout"].splitlines()[-2].split()
    assert int(count) > 90 and every == "True"


def test_python_dash_m_bench_is_the_same_entry_point():
    proc = subprocess.run(
        [sys.executable, "-m", "bench", "kin", "ik", "pkm5", "111.31", "-20", "310", "--json"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    from bench.cli import main

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["kin", "ik", "pkm5", "111.31", "-20", "310", "--json"]) == 0
    assert json.loads(proc.stdout) == json.loads(out.getvalue())
    bad = subprocess.run(
        [sys.executable, "-m", "bench", "kin", "ik", "pkm5", "x"], capture_output=True, text=True, timeout=120
    )
    assert bad.returncode == 2 and "Traceback" not in bad.stderr


def test_the_path_run_analysis_loads_no_plotting_table_or_pdf_library():
    """``bench analyze path-run`` reads :mod:`bench.reports.path_run`: importing it (through the package, whose
    public names load on first use) loads numpy only: no matplotlib, pandas, reportlab or scipy."""
    result = imported_after(
        "import bench.reports.path_run\nimport bench.reports\nassert callable(bench.reports.path_run.analyze_path_run)"
    )
    assert result["heavy"] == ["numpy"]


def test_the_reports_public_names_still_load_on_first_use():
    result = imported_after(
        "from bench.reports import LAYOUTS, write_report\nprint(len(LAYOUTS), write_report.__module__)"
    )
    assert "9 bench.reports.writing" in result["stdout"] and "matplotlib" in result["heavy"]


def test_the_reports_package_lists_exactly_the_names_its_writing_module_exports():
    import bench.reports
    import bench.reports.writing

    assert bench.reports.__all__ == bench.reports.writing.__all__
    assert all(getattr(bench.reports, name) is getattr(bench.reports.writing, name) for name in bench.reports.__all__)
