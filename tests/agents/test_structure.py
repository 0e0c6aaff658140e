"""The shape of agents/: modules small, no import circle, one convention for programs, and
the old import paths still working (with a DeprecationWarning)."""

from __future__ import annotations

import ast
import importlib
import subprocess
import sys
from pathlib import Path

import pytest

AGENTS = Path(__file__).resolve().parents[2] / "agents"
PROGRAMS = ("check", "evaluate", "identify", "lqr", "plan", "train")


def _imports(path: Path, modules: set[str]) -> set[str]:
    """The agents modules `path` imports, at the top or inside functions."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            names = [node.module] if node.module else [a.name for a in node.names]
            found |= {n.split(".")[0] for n in names}
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("agents"):
            parts = node.module.split(".")
            found |= {parts[1]} if len(parts) > 1 else {a.name for a in node.names}
    return (found & modules) - {path.stem}


def test_modules_are_small_and_import_no_circle():
    files = {p.stem: p for p in AGENTS.glob("*.py")}
    long = {name: n for name, p in files.items() if (n := len(p.read_text().splitlines())) > 400}
    assert not long, f"modules over 400 lines: {long}"
    graph = {name: _imports(p, set(files)) for name, p in files.items()}
    done: set[str] = set()

    def visit(name: str, path: tuple[str, ...]) -> None:
        assert name not in path, f"import circle: {' -> '.join(path + (name,))}"
        if name not in done:
            for dep in graph[name]:
                visit(dep, path + (name,))
            done.add(name)

    for name in graph:
        visit(name, ())
    # a library module imports no program (the programs import libraries)
    for name, deps in graph.items():
        if name not in PROGRAMS and not name.endswith("_cli"):
            programs = deps & set(PROGRAMS)
            assert not programs, f"library {name} imports programs {programs}"


@pytest.mark.parametrize("program", PROGRAMS)
def test_every_program_has_one_form(program):
    module = importlib.import_module(f"agents.{program}")
    assert module.build_parser().prog == f"python -m agents.{program}"
    assert callable(module.main)
    assert module.__doc__


def test_the_programs_are_their_library_modules():
    from agents.lqr import LQRPolicy  # the library's names, from the program's module too
    from agents.plan import plan, plan_options  # noqa: F401

    assert LQRPolicy.__module__ == "agents.lqr_policy"


@pytest.mark.slow  # a new interpreter importing gymnasium, scipy and the envs: ~4 s
def test_a_program_runs_as_a_module():
    out = subprocess.run(
        [sys.executable, "-m", "agents.lqr", "--help"],
        capture_output=True,
        text=True,
        cwd=AGENTS.parent,
        timeout=120,
    )
    assert out.returncode == 0 and "Lagrange/Acrobot-v2" in out.stdout
