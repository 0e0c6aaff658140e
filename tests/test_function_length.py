"""No function in dynamics/, envs/ or agents/ is over 80 lines (a function fits on one
screen), nested functions and methods included, counted from `def` to its last line.

Excluded: model declarations, the functions annotated `-> ModelSpec` (the bicycle's
`whipple_bicycle`, the crank's `eccentric_disk_slider` in dynamics/models/). A declaration
is data, the system written once the way the book writes it (points, velocities, T, V, Q
in order), and reads best from top to bottom; examples/ holds only such declarations and
their tasks and is not scanned. `ALLOWED` names each other exception and why; an entry
that is no longer needed fails here, so that it is removed. Modules: each says its job, and
none is past a generous smoke alarm (`SMOKE_ALARM`), which is not a target to pack to."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("dynamics", "envs", "agents")
LIMIT = 80
ALLOWED: dict[str, str] = {}


def _declaration(node: ast.AST) -> bool:
    """Whether `node` is a model declaration: a function annotated to return a ModelSpec."""
    r = node.returns
    name = r.attr if isinstance(r, ast.Attribute) else getattr(r, "id", getattr(r, "value", None))
    return name == "ModelSpec"


def long_functions(root: Path = ROOT) -> dict[str, int]:
    """'path:qualified name' -> lines, for every function over LIMIT lines that is not a
    model declaration."""
    found = {}
    for package in PACKAGES:
        for path in sorted((root / package).rglob("*.py")):
            tree = ast.parse(path.read_text(encoding="utf-8"))
            rel = path.relative_to(root).as_posix()
            todo = [(node, "") for node in tree.body]
            while todo:
                node, scope = todo.pop()
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                    name = f"{scope}{node.name}"
                    lines = node.end_lineno - node.lineno + 1
                    if not isinstance(node, ast.ClassDef) and lines > LIMIT:
                        if not _declaration(node):
                            found[f"{rel}:{name}"] = lines
                    todo += [(child, f"{name}.") for child in ast.iter_child_nodes(node)]
                else:
                    todo += [(child, scope) for child in ast.iter_child_nodes(node)]
    return found


def test_no_function_is_over_80_lines():
    long = {k: v for k, v in long_functions().items() if k not in ALLOWED}
    assert not long, (
        f"functions over {LIMIT} lines (split them into parts named for their jobs): {long}"
    )


@pytest.mark.parametrize("entry", sorted(ALLOWED))
def test_each_allowed_entry_is_still_needed(entry):
    assert entry in long_functions(), (
        f"{entry} is no longer over {LIMIT} lines: remove it from ALLOWED ({ALLOWED[entry]})"
    )


def test_the_check_finds_a_long_function_and_skips_a_declaration(tmp_path):
    body = "\n".join(f"    x{i} = {i}" for i in range(LIMIT))
    (tmp_path / "dynamics").mkdir()
    (tmp_path / "dynamics" / "m.py").write_text(
        f"class A:\n    def long(self):\n    {body.replace(chr(10), chr(10) + '    ')}\n"
        f"def spec() -> ModelSpec:\n{body}\n"
        f"def short():\n{body[: body.rindex(chr(10))]}\n"
    )
    for package in ("envs", "agents"):
        (tmp_path / package).mkdir()
    assert long_functions(tmp_path) == {"dynamics/m.py:A.long": LIMIT + 1}


SMOKE_ALARM = 800
"""A module of dynamics/, envs/ or agents/ past this many lines is a sign of two jobs in
one: a smoke alarm, not a target. Modules are split where a job ends (each names its job,
`test_every_module_says_its_job`), never packed to fit a count: the layout is the
formatter's (ruff format)."""


def _modules(root: Path = ROOT):
    for package in PACKAGES:
        yield from sorted((root / package).rglob("*.py"))


def test_every_module_says_its_job():
    """Each module opens with a docstring whose first line says what it is for."""
    silent = [
        path.relative_to(ROOT).as_posix()
        for path in _modules()
        if not (ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or "").strip()
    ]
    assert not silent, f"modules without a docstring saying their job: {silent}"


def test_no_module_sets_off_the_smoke_alarm():
    lines = {
        path.relative_to(ROOT).as_posix(): len(path.read_text(encoding="utf-8").splitlines())
        for path in _modules()
    }
    long = {path: n for path, n in lines.items() if n > SMOKE_ALARM}
    assert not long, f"modules over {SMOKE_ALARM} lines (do they hold two jobs?): {long}"
