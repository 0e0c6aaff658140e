"""The house's rules, checked on the source: no module writes another object's private
fields, and the runtime's step has two routes (the fused step and `System`'s one unchecked
step)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from dynamics.system import System
from envs.step import Step

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("dynamics", "envs", "agents")

PRIVATE_WRITE = re.compile(
    r"\b(?!self\b|cls\b)[A-Za-z_]\w*\._(?!_)\w+(\[[^]]*\])?\s*(=|\+=|-=)(?!=)"
)
"""`obj._name = ...` (or `obj._name[...] = ...`) with obj another object than self."""

ALLOWED = {
    "dynamics/stepping.py": "the kernels' address table kept on a generated module",
    "dynamics/cache.py": "a numba dispatcher's disk cache set as njit(cache=True) sets it",
}


def private_writes(root: Path = ROOT) -> list[str]:
    found = []
    for package in PACKAGES:
        for path in sorted((root / package).rglob("*.py")):
            rel = path.relative_to(root).as_posix()
            for k, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
                code = line.split("#", 1)[0]
                if PRIVATE_WRITE.search(code) and rel not in ALLOWED:
                    found.append(f"{rel}:{k}: {line.strip()}")
    return found


def test_no_module_writes_another_objects_private_fields():
    assert private_writes() == []


def test_the_check_finds_a_private_write(tmp_path):
    for package in PACKAGES:
        (tmp_path / package).mkdir()
    (tmp_path / "envs" / "m.py").write_text("rt._fused = None\nself._x = 1\nrt._K[0] = 2\n")
    assert [f.split(":")[1] for f in private_writes(tmp_path)] == ["1", "3"]


def test_system_offers_one_unchecked_step():
    assert [n for n in dir(System) if n.endswith("_unchecked")] == ["step_unchecked"]


def test_the_step_offers_one_call():
    public = [n for n in vars(Step) if not n.startswith("_") and callable(vars(Step)[n])]
    assert sorted(public) == ["bind", "evaluate", "rows", "separate", "step"]


def _imports(path: Path) -> set[str]:
    """The modules `path` imports (relative imports resolved), anywhere in it."""
    import ast

    rel = path.relative_to(ROOT).with_suffix("")
    package = rel.parts[:-1]
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            base = list(package[: len(package) - node.level + 1]) if node.level else []
            module = ".".join([*base, *(node.module or "").split(".")]).strip(".")
            out |= {f"{module}.{a.name}" for a in node.names}
            if node.module:  # `from . import x` imports x, not the package
                out.add(module)
        elif isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
    return out


def _reaches(folder: str, target: str) -> list[str]:
    return [
        p.relative_to(ROOT).as_posix()
        for p in sorted((ROOT / folder).rglob("*.py"))
        if any(m == target or m.startswith(target + ".") for m in _imports(p))
    ]


def test_the_wings_arrows_point_one_way():
    """Scoring reads learning (the probe, the run directories); learning never imports
    scoring. envs/__init__ imports envs.docs; envs.docs never imports the package back."""
    assert _reaches("agents/learning", "agents.scoring") == []
    assert _reaches("agents/scoring", "agents.learning") != []
    assert "envs" not in _imports(ROOT / "envs" / "docs.py")


@pytest.mark.parametrize(
    "statement", ["import envs.arm", "from envs import disk", "from envs.bead import TASK"]
)
def test_a_built_in_task_s_old_home_says_where_it_went(statement):
    """Before 1.0 the old home is no shim: importing it ends in one line naming the new one."""
    with pytest.raises(ImportError, match=r"envs\.(arm|disk|bead) moved to envs\.tasks\."):
        exec(statement, {})
