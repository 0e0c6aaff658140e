"""Keep the built-in env docstrings' generated tables current: `python -m envs.docs`.

Each built-in env module's docstring carries the action, observation and reward-term
tables generated from its task declaration (`envs.task.document`); this rewrites them in
place (atomically) and, with `--check`, only reports which are stale.
"""

from __future__ import annotations

import argparse
import ast
import importlib
import sys
from pathlib import Path

from dynamics.cache import write_atomic

from .task import document

MODULES = ("envs.arm", "envs.acrobot", "envs.disk", "envs.bead", "envs.crank")


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
