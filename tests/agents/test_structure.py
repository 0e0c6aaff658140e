"""The shape of agents/: three wings (control, learning, scoring) under the programs, modules
small, no import circle, one convention for programs. The flat layout's paths
(agents.lqr_policy and the like) are gone without shims: only programs and shared helpers
sit at the top."""

from __future__ import annotations

import ast
import importlib
import subprocess
import sys
from pathlib import Path

import pytest

AGENTS = Path(__file__).resolve().parents[2] / "agents"
PROGRAMS = ("check", "evaluate", "identify", "lqr", "plan", "train")
WINGS = ("control", "learning", "scoring")
SHARED = ("common", "params", "values")  # helpers at the top, beside the programs


def _modules() -> dict[str, Path]:
    """Every module of agents/ by its dotted name below the package ('control.linear')."""
    return {
        ".".join(p.relative_to(AGENTS).with_suffix("").parts): p
        for p in AGENTS.rglob("*.py")
        if p.name != "__init__.py"
    }


def _imports(name: str, path: Path, modules: set[str]) -> set[str]:
    """The agents modules `name` imports, at the top or inside functions."""
    package = name.split(".")[:-1]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if not isinstance(node, ast.ImportFrom):
            continue
        if node.level:
            base = package[: len(package) - node.level + 1] + (node.module or "").split(".")
        elif (node.module or "").split(".")[0] == "agents":
            base = node.module.split(".")[1:]
        else:
            continue
        base = [part for part in base if part]
        for alias in node.names:
            full = ".".join(base + [alias.name])
            found.add(full if full in modules else ".".join(base))
    return (found & modules) - {name}


def _wing(name: str) -> str:
    return name.split(".")[0] if "." in name else "top"


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    files = _modules()
    return {name: _imports(name, path, set(files)) for name, path in files.items()}


def test_the_top_holds_programs_and_shared_helpers_and_the_rest_sits_in_a_wing():
    top = {name for name in _modules() if "." not in name}
    assert top == set(PROGRAMS) | set(SHARED), f"at the top beyond programs and helpers: {top}"
    wings = {p.name for p in AGENTS.iterdir() if (p / "__init__.py").exists()}
    assert wings == set(WINGS)
    for wing in WINGS:
        assert importlib.import_module(f"agents.{wing}").__doc__
    assert (AGENTS / "learning" / "hyperparams" / "ppo.yml").is_file()


def test_modules_import_no_circle(graph):
    # (their size: tests/test_function_length.py's smoke alarm, for every package alike)
    done: set[str] = set()

    def visit(name: str, path: tuple[str, ...]) -> None:
        assert name not in path, f"import circle: {' -> '.join(path + (name,))}"
        if name not in done:
            for dep in graph[name]:
                visit(dep, path + (name,))
            done.add(name)

    for name in graph:
        visit(name, ())


def test_no_wing_imports_a_program(graph):
    # the programs import the wings, never the other way round
    for name, deps in graph.items():
        if name not in PROGRAMS:
            programs = deps & set(PROGRAMS)
            assert not programs, f"library {name} imports programs {programs}"


def test_control_stands_on_its_own(graph):
    # a controller needs neither a learner nor a scorer; the shared helpers need no wing
    for name, deps in graph.items():
        if _wing(name) == "control" or name in ("common", "values"):
            others = {d for d in deps if _wing(d) in ("learning", "scoring")}
            assert not others, f"{name} imports {others}"


@pytest.mark.parametrize("program", PROGRAMS)
def test_every_program_has_one_form(program):
    module = importlib.import_module(f"agents.{program}")
    assert module.build_parser().prog == f"python -m agents.{program}"
    assert callable(module.main)
    assert module.__doc__


def test_the_programs_are_their_library_modules():
    from agents.lqr import LQRPolicy  # the library's names, from the program's module too
    from agents.plan import plan, plan_options  # noqa: F401

    assert LQRPolicy.__module__ == "agents.control.lqr_policy"


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
