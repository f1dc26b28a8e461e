"""A run says what it ran on: ``bench run`` names its rig (--station or --sim) or is refused, ``bench runs`` shows
simulated runs as such, and a resume on another device under test or another rig is refused, writing nothing."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from cli_lines import one_error_line as _one_error_line
from cli_runs import store_dump

from bench.cli import main
from bench.store import Store

ROOT = Path(__file__).resolve().parents[1]
QUICK = ROOT / "examples" / "iso9283_pose_quick.toml"
STATION = ROOT / "examples" / "stations" / "pkm5_mice.toml"


@pytest.fixture(scope="module")
def rehearsed(tmp_path_factory) -> Path:
    """A store holding one iso9283_pose_quick run on the pkm5_mice station rehearsed on simulators, left aborted
    (resumable) as a stop would leave it."""
    store = tmp_path_factory.mktemp("rig") / "bench.db"
    assert (
        main(
            [
                "run",
                str(QUICK),
                "--station",
                str(STATION),
                "--sim",
                "--store",
                str(store),
                "--no-progress",
                "--speed-factor",
                "300",
            ]
        )
        == 0
    )
    with Store(store) as opened:
        opened.set_status(1, "aborted", "interrupted (SIGTERM)")
    return store


def test_run_without_a_rig_is_refused_in_one_line_naming_both_flags(tmp_path, capsys):
    store = tmp_path / "bench.db"
    assert main(["run", str(QUICK), "--store", str(store), "--no-progress"]) == 2
    assert _one_error_line(capsys) == (
        f"bench: error: bench run {QUICK}: no rig named, expected --station "
        "STATION.toml (the bench's devices) or --sim (the simulator)"
    )
    assert not store.exists()


@pytest.mark.parametrize(
    "rig, refusal",
    [
        (["--station", "no-such-station.toml"], "no-such-station.toml: cannot read the station file"),
        (["--port", "/dev/null"], "--port: protocol 'iso9283_pose' needs pose"),
    ],
)
def test_a_run_refused_at_its_rig_leaves_no_new_store_behind(tmp_path, capsys, rig, refusal):
    """A mistyped station file or a rig without the protocol's instrument is refused in one line and creates no
    empty store file (issue 32: a refused command writes nothing)."""
    store = tmp_path / "bench.db"
    assert main(["run", str(QUICK), "--store", str(store), "--no-progress", *rig]) == 2
    assert _one_error_line(capsys).startswith(f"bench: error: {refusal}")
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_runs_shows_simulated_runs_as_such(rehearsed, tmp_path, capsys):
    store = tmp_path / "bench.db"
    store.write_bytes(rehearsed.read_bytes())
    with Store(store) as opened:  # a run on hardware: its settings name a station and no simulator
        settings = {key: value for key, value in opened.run(1).settings.items() if key != "simulator"}
        opened.start_run(protocol_name="iso9283_pose", protocol_version="1", robot="pkm5", config={}, settings=settings)
        opened.set_status(2, "completed")
    capsys.readouterr()
    assert main(["runs", "--store", str(store)]) == 0
    header, first, second = capsys.readouterr().out.splitlines()
    assert header.split()[:6] == ["id", "bench", "protocol", "robot", "rig", "status"]
    assert first.split()[4:6] == ["pkm5", "simulated"] and second.split()[4:6] == ["pkm5", "hardware"]
    assert main(["runs", "--store", str(store), "--json"]) == 0
    assert [json.loads(line)["simulated"] for line in capsys.readouterr().out.splitlines()] == [True, False]


@pytest.mark.parametrize(
    "line, changed, what",
    [
        ('serial = "PKM5-0001"', 'serial = "PKM5-0002"', "device under test is PKM5-0001"),
        ('asset = "INV-0001"', 'asset = "INV-0009"', "robot asset is INV-0001"),
    ],
)
def test_resume_with_another_device_under_test_is_refused_and_writes_nothing(
    rehearsed, tmp_path, capsys, line, changed, what
):
    store = tmp_path / "bench.db"
    store.write_bytes(rehearsed.read_bytes())
    other = tmp_path / "pkm5_mice_other.toml"
    text = STATION.read_text()
    assert text.count(line) == 1
    other.write_text(text.replace(line, changed))
    before = store_dump(store)
    capsys.readouterr()
    named = changed.split('"')[1]
    assert main(["resume", "1", "--station", str(other), "--sim", "--store", str(store), "--no-progress"]) == 2
    assert _one_error_line(capsys) == (
        f"bench: error: the resumed run: {what}, the station {other} names {named}; "
        f"resume it with the station it ran on: --station {STATION} --sim"
    )
    assert store_dump(store) == before


@pytest.mark.parametrize(
    "options, asked",
    [([], "resume named no rig"), (["--sim"], "resume asked for the simulator (--sim)")],
)
def test_resume_of_a_station_run_on_the_simulator_is_refused_naming_its_rig_and_writes_nothing(
    rehearsed, tmp_path, capsys, options, asked
):
    """A bare ``bench resume RUN`` of a station run is told it named no rig (not that it asked for --sim) and
    which options resume the run on its own rig (issue 32, item 10: refused "with no hint")."""
    store = tmp_path / "bench.db"
    store.write_bytes(rehearsed.read_bytes())
    before = store_dump(store)
    capsys.readouterr()
    assert main(["resume", "1", "--store", str(store), "--no-progress", *options]) == 2
    assert _one_error_line(capsys) == (
        f"bench: error: the resumed run: ran on station {STATION} rehearsed on "
        f"simulators (--sim), {asked}; resume it on the rig it ran on: --station {STATION} --sim"
    )
    assert store_dump(store) == before
