"""`pip install bench` alone runs the main job: the demo never imports an optional extra, and a missing extra is one
line naming the extra that installs it (bench/extras.py)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest

from bench.errors import ConfigError
from bench.extras import EXTRAS, ensure_installed, install_hint, require

#: The optional modules of pyproject.toml's extras (numba: the `fast` extra, which motion.kernels detects itself).
OPTIONAL = (*EXTRAS, "numba")

# A site hook that makes every optional module look uninstalled, in this process and every child it starts
# (the simulators), as on a machine where only `pip install bench` ran.
SITECUSTOMIZE = textwrap.dedent(f"""
    import sys
    from importlib.machinery import PathFinder
    class _NotInstalled:  # the path finder, blind to the optional modules: import and find_spec say "not installed"
        @staticmethod
        def find_spec(name, path=None, target=None):
            if name.split(".")[0] in {OPTIONAL!r}:
                return None
            return PathFinder.find_spec(name, path, target)
        invalidate_caches = staticmethod(PathFinder.invalidate_caches)
    sys.meta_path[:] = [_NotInstalled if finder is PathFinder else finder for finder in sys.meta_path]
""")


@pytest.mark.slow
def test_the_demo_runs_without_any_extra(tmp_path):
    hook = tmp_path / "hook"
    hook.mkdir()
    (hook / "sitecustomize.py").write_text(SITECUSTOMIZE)
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(hook), *filter(None, [os.environ.get("PYTHONPATH")])]),
        "BENCH_TEST_SIMULATOR_FORKS": "0",
    }
    probe = subprocess.run([sys.executable, "-c", "import cv2"], env=env, capture_output=True, text=True)
    assert "No module named 'cv2'" in probe.stderr  # the hook works: the extras are gone for the demo below
    out = tmp_path / "demo"
    done = subprocess.run(
        [sys.executable, "-m", "bench", "demo", "--out", str(out), "--cycles", "3"],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    assert (out / "bench.db").is_file()
    assert any(path.suffix == ".pdf" for path in out.iterdir())


@pytest.mark.parametrize("module", sorted(EXTRAS))
def test_a_missing_extra_names_the_extra_that_installs_it(module, monkeypatch):
    monkeypatch.setitem(sys.modules, module, None)  # Python's own "not importable" marker
    extra = EXTRAS[module][0]
    with pytest.raises(ConfigError, match=rf"pip install 'bench\[{extra}\]'"):
        require(module)
    assert install_hint(module).endswith(f"pip install 'bench[{extra}]'")


def test_ensure_installed_refuses_a_module_that_is_not_there():
    EXTRAS_BEFORE = dict(EXTRAS)
    EXTRAS["bench_no_such_module"] = ("nothing", "this test")
    try:
        with pytest.raises(ConfigError, match=r"this test needs bench_no_such_module: pip install 'bench\[nothing\]'"):
            ensure_installed("bench_no_such_module")
    finally:
        EXTRAS.clear()
        EXTRAS.update(EXTRAS_BEFORE)
