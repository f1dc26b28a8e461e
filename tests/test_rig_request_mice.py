"""The mice a run names on the command line (``--mouse-xy``, ``--mouse-xz``, ``--mouse-xz-mount``) or in the window:
they reach the station the port describes, and are refused, never ignored, where they cannot apply."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.cli import main
from bench.errors import ConfigError
from bench.launch import RigRequest, _station

ROOT = Path(__file__).resolve().parents[1]
QUICK = ROOT / "examples" / "iso9283_pose_quick.toml"
STATION = ROOT / "examples" / "stations" / "pkm5_mice.toml"


@pytest.mark.parametrize(("mount", "expected"), [(None, "platform"), ("guided", "guided"), ("platform", "platform")])
def test_the_mount_reaches_the_station_the_port_describes(mount, expected):
    request = RigRequest(port="/dev/ttyUSB0", mouse_xy="/dev/a", mouse_xz="/dev/b", mouse_xz_mount=mount)
    station = _station(request, "pkm5", "assembled")
    assert station is not None
    mice = station.sensor("mice")
    assert (mice.xy, mice.xz, mice.xz_mount) == ("/dev/a", "/dev/b", expected)


def test_a_mount_without_mice_is_refused():
    with pytest.raises(ConfigError, match="an x-z mount given without mice"):
        _station(RigRequest(port="/dev/ttyUSB0", mouse_xz_mount="guided"), "pkm5", "assembled")


@pytest.mark.parametrize(
    ("where", "named"),
    [
        (["--sim"], ["--mouse-xy", "a", "--mouse-xz", "b"]),
        (["--sim"], ["--mouse-xz-mount", "guided"]),
        (["--station", str(STATION)], ["--mouse-xy", "a", "--mouse-xz", "b"]),
        (["--station", str(STATION), "--sim"], ["--mouse-xz-mount", "guided"]),
    ],
)
def test_mice_named_where_they_cannot_apply_are_one_line_and_nothing_is_stored(capsys, tmp_path, where, named):
    db = tmp_path / "b.db"
    assert main(["run", str(QUICK), "--store", str(db), "--no-progress", *where, *named]) == 2
    err = capsys.readouterr().err.strip()
    place = "a station" if "--station" in where else "the simulator"
    assert err.startswith(f"bench: error: mice: named with {place}") and "expected them with a --port only" in err
    assert len(err.splitlines()) == 1 and not db.exists()


def test_an_unknown_mount_names_the_choices(capsys, tmp_path):
    with pytest.raises(SystemExit) as exit_:
        main(["run", str(QUICK), "--store", str(tmp_path / "b.db"), "--port", "p", "--mouse-xz-mount", "sideways"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "--mouse-xz-mount: invalid choice: 'sideways' (choose from 'platform', 'guided')" in err
