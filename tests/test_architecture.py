"""The architecture's import contracts (``[tool.importlinter]`` in pyproject.toml), checked on every test run:
production code never imports the simulators, the GUI never imports the command line, motion/ and
bench.metrology stay pure, and the layers import downwards only."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import grimp

ROOT = Path(__file__).resolve().parents[1]


def test_import_contracts_are_kept():
    lint = Path(sys.executable).with_name("lint-imports")
    result = subprocess.run([str(lint), "--no-cache"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-2000:]
    assert "4 kept, 0 broken" in result.stdout


def test_a_broken_contract_is_caught(tmp_path):
    """The check can fail: a contract that forbids what bench.rigs really imports (its drivers) is reported
    broken."""
    config = tmp_path / "contracts.toml"
    config.write_text(
        '[tool.importlinter]\nroot_packages = ["bench"]\n\n[[tool.importlinter.contracts]]\n'
        'name = "rigs without robots"\ntype = "forbidden"\nsource_modules = ["bench.rigs"]\n'
        'forbidden_modules = ["bench.robots"]\n'
    )
    lint = Path(sys.executable).with_name("lint-imports")
    result = subprocess.run(
        [str(lint), "--no-cache", "--config", str(config)], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert result.returncode == 1 and "rigs without robots BROKEN" in result.stdout


def _import_cycles(graph) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan), imports inside functions included."""
    modules = sorted(graph.modules)
    edges = {m: sorted(set(graph.find_modules_directly_imported_by(m)) & set(modules)) for m in modules}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    cycles = []
    for root in modules:  # iterative, so a deep package cannot exhaust the recursion limit
        if root in index:
            continue
        work = [(root, 0)]
        while work:
            node, child = work.pop()
            if child == 0:
                index[node] = low[node] = len(index)
                stack.append(node)
            if child < len(edges[node]):
                work.append((node, child + 1))
                nxt = edges[node][child]
                if nxt not in index:
                    work.append((nxt, 0))
                elif nxt in stack:
                    low[node] = min(low[node], index[nxt])
                continue
            for nxt in edges[node]:
                if nxt in stack:
                    low[node] = min(low[node], low[nxt])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    cycles.append(sorted(component))
    return cycles


def test_no_module_imports_itself_through_others():
    """No import circle, not even one hidden inside a function (issue 35: reports/document <-> orientation and
    motion/pkm5 compiled <-> fk were two)."""
    assert _import_cycles(grimp.build_graph("bench", "motion")) == []


def test_the_circle_finder_finds_a_circle():
    class Graph:
        modules = {"a", "b", "c"}

        @staticmethod
        def find_modules_directly_imported_by(module):
            return {"a": {"b"}, "b": {"a"}, "c": {"a"}}[module]

    assert _import_cycles(Graph()) == [["a", "b"]]
