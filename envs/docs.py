"""An env's documentation from its task declaration, and `python -m envs.docs`.

`describe(task)` writes the action, observation and reward-term tables of a task (at its
default parameters); `document(doc, task)` puts them into a Gymnasium-style env docstring.
Each built-in env module's docstring carries those tables; `python -m envs.docs` rewrites
them in place (atomically) and, with `--check`, only reports which are stale.
"""

from __future__ import annotations

import argparse
import ast
import importlib
import sys
import textwrap
from pathlib import Path

from dynamics.cache import write_atomic

from .plant import Plant
from .task import Task

MODULES = ("envs.arm", "envs.acrobot", "envs.disk", "envs.bead", "envs.crank", "envs.bicycle")


def describe(task: Task, **params) -> str:
    """The '## Action Space', '## Observation Space' and '## Reward terms' sections (Markdown)
    of `task` at these model parameters (defaults otherwise)."""
    return tables(Plant.build(task, params))


def tables(plant: Plant) -> str:
    """The generated sections of the env docstring, for a built plant."""
    task = plant.task
    prose = (
        f"`Box(-1, 1, ({len(task.actuated)},), float32)`; action -1 and 1 are the input's "
        "limits (`max_input`, overridable when the env is made). Actions outside [-1, 1] are "
        "clipped; NaN or inf actions raise ValueError, complex ones TypeError."
    )
    symmetric = bool((plant.input_low == -plant.input_high).all())
    lines = ["## Action Space", *textwrap.wrap(prose, 88), ""]
    if symmetric:
        lines += ["| Num | Input | Limit |", "|-----|-------|-------|"]
        for i, (name, limit) in enumerate(zip(task.actuated, plant.input_high)):
            lines.append(f"| {i} | {name} | {limit:.4g} |")
    else:
        lines += ["| Num | Input | Min | Max |", "|-----|-------|-----|-----|"]
        for i, (name, lo, hi) in enumerate(zip(task.actuated, plant.input_low, plant.input_high)):
            lines.append(f"| {i} | {name} | {lo:.4g} | {hi:.4g} |")
    lines += [
        "",
        "## Observation Space",
        f"`Box(low, high, ({plant.obs_size},), float32)`:",
        "",
        "| Num | Observation | Min | Max | Unit |",
        "|-----|-------------|-----|-----|------|",
    ]
    for i, (label, lo, hi, unit) in enumerate(plant.columns):
        lines.append(f"| {i} | {label} | {lo:.4g} | {hi:.4g} | {unit} |")
    lines += ["", "## Reward terms", "", "| Term | Min | Max | Meaning |", "|---|---|---|---|"]
    for term, lo, hi in zip(task.terms, plant.term_low, plant.term_high):
        lines.append(f"| {term.name} | {lo:.4g} | {hi:.4g} | {term.doc} |")
    return "\n".join(lines)


def document(doc: str, task: Task, **params) -> str:
    """`doc` (a Gymnasium-style env docstring) with the generated tables of `task` (at its
    default parameters) put between its '## Description' and '## Rewards' sections,
    replacing earlier generated ones."""
    generated = describe(task, **params)
    head, sep, tail = doc.partition("## Rewards\n")
    if not sep:
        return doc.rstrip() + "\n\n" + generated + "\n"
    head = head.split("## Action Space\n")[0].rstrip() + "\n\n"
    return head + generated + "\n\n" + sep + tail


def regenerated(module_name: str) -> tuple[Path, str, str]:
    """(path, current source, source with the docstring's tables regenerated)."""
    module = importlib.import_module(module_name)
    path = Path(module.__file__)
    source = path.read_text(encoding="utf-8")
    tree = ast.parse(source)
    node = tree.body[0]
    doc = ast.get_docstring(tree, clean=False)
    if not isinstance(node, ast.Expr) or doc is None:
        raise ValueError(f"{path} has no module docstring.")
    new_doc = document(doc, module.TASK)
    lines = source.splitlines(keepends=True)
    literal = '"""' + new_doc.replace("\\", "\\\\") + '"""\n'
    new = "".join(lines[: node.lineno - 1]) + literal + "".join(lines[node.end_lineno :])
    return path, source, new


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m envs.docs", description=__doc__)
    parser.add_argument("--check", action="store_true", help="report stale docstrings only")
    args = parser.parse_args(argv)
    stale = []
    for name in MODULES:
        path, old, new = regenerated(name)
        if old != new:
            stale.append(str(path))
            if not args.check:
                write_atomic(path, new)
    verb = "stale" if args.check else "rewrote"
    print(f"{verb}: {', '.join(stale)}" if stale else "all env docstrings are current")
    return 1 if (args.check and stale) else 0


if __name__ == "__main__":
    sys.exit(main())
