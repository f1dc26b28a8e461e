"""Long ``bench kin workspace`` runs show a progress bar on stderr (stdout keeps the result alone)."""

import json

import pytest

from bench.cli import main
from bench.commands import kin
from motion import pkm5, prus3


def test_the_workspace_estimate_reports_its_samples_as_it_goes():
    seen: list[int] = []
    with_progress = pkm5.estimate_workspace(samples=50_000, hull_points=200, seed=3, progress=seen.append)
    assert seen == [20_000, 40_000, 50_000]  # one call per chunk of 20,000 box samples
    assert with_progress.volume == pkm5.estimate_workspace(samples=50_000, hull_points=200, seed=3).volume
    counted: list[int] = []
    prus3.workspace_volume(1200, chunk=500, progress=counted.append)
    assert counted == [500, 1000, 1200]


@pytest.mark.parametrize(
    ("argv", "label"),
    [
        (
            ["kin", "workspace", "pkm5", "--samples", "50000", "--hull-points", "200"],
            "pkm5 constant-orientation workspace, samples",
        ),
        (["kin", "workspace", "prus3", "--samples", "3000"], "prus3 workspace, samples"),
    ],
)
def test_a_long_workspace_run_draws_a_bar_on_stderr(capsys, monkeypatch, argv, label):
    monkeypatch.setattr(kin, "SHOW_AFTER_S", 0.0)
    assert main([*argv, "--json"]) == 0
    out, err = capsys.readouterr()
    samples = argv[argv.index("--samples") + 1]
    assert label in err and f"{samples}/{samples}" in err
    assert json.loads(out)["samples"] == int(samples)


def test_no_progress_and_short_runs_keep_stderr_empty(capsys, monkeypatch):
    monkeypatch.setattr(kin, "SHOW_AFTER_S", 0.0)
    assert main(["kin", "workspace", "pkm5", "--samples", "30000", "--hull-points", "200", "--no-progress"]) == 0
    assert capsys.readouterr().err == ""
    monkeypatch.setattr(kin, "SHOW_AFTER_S", 3600.0)
    assert main(["kin", "workspace", "pkm5", "--samples", "30000", "--hull-points", "200"]) == 0
    assert capsys.readouterr().err == ""
