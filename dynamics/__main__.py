"""Command line: `python -m dynamics list`, `show NAME [--latex]`,
`cache [list | prune [--max-size 500M] [--older-than 30d]] [--clear]`."""

from __future__ import annotations

import argparse
import sys

from .model import get_model, list_models

DISPLAY_LIMIT = 20_000
"""Models whose M and F (as generated) have more nodes than this are not simplified for
display: that takes hours (the bicycle's have 111,626)."""


def show(name: str, latex: bool = False) -> str:
    """The derived equations of model `name` as text (pretty) or LaTeX."""
    import sympy as sp
    from sympy.physics.vector.printing import VectorPrettyPrinter, vlatex

    pretty_printer = VectorPrettyPrinter({"wrap_line": False, "use_unicode": True})

    def fmt(expr) -> str:
        return vlatex(expr) if latex else pretty_printer.doprint(sp.sympify(expr))

    model = get_model(name)
    d = model.derived
    lines = [f"{name}: coordinates {', '.join(model.coordinates)}"]
    if model.inputs:
        lines.append(f"inputs: {', '.join(model.inputs)}")
    lines.append(
        "parameters: "
        + ", ".join(f"{k} = {v:g} {model.units[k]}" for k, v in model.parameters.items())
    )
    lines.append("")
    from .calculus import size

    nodes = sum(size(e) for e in (*d.code.mass, *d.code.forcing))
    if nodes > DISPLAY_LIMIT:
        lines.append(
            f"Lagrange's equations: M and F run to {nodes:,} nodes, too large to simplify and "
            "print; the compiled model evaluates them (System.linearize gives their "
            "linearisation; for the bicycle, `python -m dynamics.bicycle`)."
        )
        return "\n".join(lines)
    lines.append("Lagrange's equations (each = 0):")
    for eq in model.equations():
        lines.append(fmt(eq))
    if d.constraint_matrix.rows:
        lines.append("")
        lines.append("Nonholonomic constraints (each = 0):")
        for c in model.spec.constraints:
            lines.append(fmt(c))
    for key, expr in d.outputs.items():
        lines.append("")
        lines.append(f"{key} =")
        lines.append(fmt(expr))
    return "\n".join(lines)


def cache_command(parser, args) -> int:
    """`cache [list]`: each entry, least recently used first, with its size and the bound;
    `cache prune`: remove by size or age (dynamics.pruning); `cache --clear`: everything."""
    import shutil
    import time

    from . import cache, pruning

    try:
        root = cache.cache_dir()
        bound = pruning.limit()
        size, age = args.max_size, args.older_than
        max_size = None if size is None else pruning.parse_size(size, "--max-size")
        older = None if age is None else pruning.parse_age(age)
    except (OSError, ValueError) as exc:
        parser.exit(2, f"{parser.prog}: error: {exc}\n")
    if (max_size is not None or older is not None) and args.action != "prune":
        parser.exit(2, f"{parser.prog}: error: --max-size and --older-than go with prune.\n")
    if args.clear:
        files = sorted(root.glob("*.py"))
        for f in files + sorted(root.glob(".*.lock")):
            f.unlink(missing_ok=True)
        for folder in ("__pycache__", pruning.FUNCTIONS):
            shutil.rmtree(root / folder, ignore_errors=True)
        print(f"removed {len(files)} compiled modules and the task functions' code from {root}")
        return 0
    if args.action == "prune":
        if max_size is None and older is None:
            max_size = bound
        removed = pruning.prune(root, max_bytes=max_size, older_than=older)
        if removed is None:
            print(f"another process is pruning {root}; nothing done")
            return 0
        freed = sum(e.size for e in removed)
        print(f"removed {len(removed)} entries ({freed / 2**20:.1f} MiB) from {root}")
        return 0
    listed = pruning.entries(root)
    total = sum(e.size for e in listed)
    steps = [e for e in listed if e.name.startswith("step_")]  # envs' fused steps
    functions = [e for e in listed if e.name.startswith(pruning.FUNCTIONS)]
    print(
        f"{root}: {len(listed) - len(steps) - len(functions)} compiled models, {len(steps)} "
        f"compiled env steps, {len(functions)} compiled task functions; "
        f"{total / 2**20:.1f} MiB of a bound of {bound / 2**20:.0f} MiB "
        f"(${pruning.LIMIT_ENV}); least recently used first:"
    )
    now = time.time()
    for e in listed:
        print(f"  {e.name}  {e.size / 2**10:.0f} KiB, used {(now - e.last_used) / 3600:.1f} h ago")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m dynamics", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("list", help="list the registered models")
    p_show = sub.add_parser("show", help="print a model's derived equations")
    p_show.add_argument("name", help="model name (see `list`)")
    p_show.add_argument("--latex", action="store_true", help="print LaTeX instead of text")
    p_cache = sub.add_parser(
        "cache",
        help="list the compiled-model cache, prune it (least recently used first) or --clear it",
    )
    p_cache.add_argument("action", nargs="?", choices=("list", "prune"), default="list")
    p_cache.add_argument(
        "--max-size", help="prune: to at most this size, e.g. 500M (default: the bound)"
    )
    p_cache.add_argument(
        "--older-than", help="prune: also every entry unused this long, e.g. 30d, 12h"
    )
    p_cache.add_argument("--clear", action="store_true", help="delete every cached model")
    args = parser.parse_args(argv)
    if args.command == "cache":
        return cache_command(parser, args)
    if args.command == "list":
        print("\n".join(list_models()))
        return 0
    try:
        print(show(args.name, args.latex))
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
