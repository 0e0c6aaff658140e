"""The house's rules, checked on the source: no module writes another object's private
fields, and the runtime's step has two routes (the fused step and `System`'s one unchecked
step)."""

from __future__ import annotations

import re
from pathlib import Path

from dynamics.system import System
from envs.step import Step

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("dynamics", "envs", "agents")

PRIVATE_WRITE = re.compile(
    r"\b(?!self\b|cls\b)[A-Za-z_]\w*\._(?!_)\w+(\[[^]]*\])?\s*(=|\+=|-=)(?!=)"
)
"""`obj._name = ...` (or `obj._name[...] = ...`) with obj another object than self."""

ALLOWED = {"dynamics/stepping.py": "the kernels' address table kept on a generated module"}


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
