"""Command line: `python -m dynamics list`, `show NAME [--latex]`, `cache [--clear]`."""

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


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m dynamics", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("list", help="list the registered models")
    p_show = sub.add_parser("show", help="print a model's derived equations")
    p_show.add_argument("name", help="model name (see `list`)")
    p_show.add_argument("--latex", action="store_true", help="print LaTeX instead of text")
    p_cache = sub.add_parser("cache", help="show (or --clear) the compiled-model cache")
    p_cache.add_argument("--clear", action="store_true", help="delete every cached model")
    args = parser.parse_args(argv)
    if args.command == "cache":
        from . import cache

        try:
            root = cache.cache_dir()
        except OSError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        files = sorted(root.glob("*.py"))
        if args.clear:
            import shutil

            for f in files + sorted(root.glob(".*.lock")):
                f.unlink(missing_ok=True)
            shutil.rmtree(root / "__pycache__", ignore_errors=True)
            print(f"removed {len(files)} compiled modules from {root}")
        else:
            steps = [f for f in files if f.name.startswith("step_")]  # envs' fused steps
            print(
                f"{root}: {len(files) - len(steps)} compiled models, {len(steps)} compiled "
                "env steps"
            )
            for f in files:
                print(f"  {f.name}")
        return 0
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
