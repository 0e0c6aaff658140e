"""An env's documentation from its task declaration, and `python -m envs.docs`.

`describe(task)` writes the action, observation and reward-term tables of a task (at its
default parameters); `document(doc, task)` puts them into a Gymnasium-style env docstring.
Each built-in env module's docstring carries those tables; `python -m envs.docs` rewrites
them in place (atomically) and, with `--check`, only reports which are stale.
"""

from __future__ import annotations

import argparse
import ast
import functools
import importlib
import re
import sys
import textwrap
from pathlib import Path

from dynamics.cache import write_atomic

from . import tasks
from .plant import Plant
from .task import Task

_SOURCE = Path(__file__).read_text(encoding="utf-8")
MODULES = tuple(f"envs.tasks.{name}" for name in tasks.MODULES)


def describe(task: Task, **params) -> str:
    """The '## Action Space', '## Observation Space' and '## Reward terms' sections (Markdown)
    of `task` at these model parameters (defaults otherwise)."""
    return tables(Plant.build(task, params))


def cell(text) -> str:
    """Text for a Markdown table cell: a '|' in it (|action|^2) would end the cell."""
    return str(text).replace("|", r"\|")


def _length_power(unit: str) -> int:
    """The power of the metre in a unit written like 'kg*m^2', 'm/s^2', 'N/m', '1/m'
    (N and J count their metres too)."""
    power, sign = 0, 1
    for token in re.split(r"([*/ ])", unit.replace("**", "^")):
        if token in ("*", " ", ""):
            continue
        if token == "/":
            sign = -1
            continue
        base, _, exp = token.partition("^")
        per = {"m": 1, "N": 1, "J": 2}.get(base, 0)
        power += sign * per * int(exp or 1)
    return power


def coordinate_kinds(spec) -> dict:
    """{coordinate: True for an angle, False for a length} of a model spec, from the
    dimensions of T: the coefficient of q'^2 carries m^2 more than a mass for an angle
    (kg*m^2 against kg). It is evaluated at one generic point twice, the second time with
    every length doubled (each parameter by its unit's power of the metre, the coordinates
    decided to be lengths, all rates): the ratio is 4 for an angle, 1 for a length. A
    coefficient that reads coordinates not yet decided (m r^2 waits for r) is taken in a
    later round. Left undecided: an angle where it appears in a circular function."""
    import sympy as sp

    t = spec_time()
    coords = list(spec.coordinates)
    rates = [sp.Derivative(q, t) for q in coords]
    plain = sp.symbols(f"q0:{len(coords)}"), sp.symbols(f"qd0:{len(coords)}")
    kinetic = sp.sympify(spec.kinetic).xreplace(dict(zip(rates, plain[1])))
    kinetic = kinetic.xreplace(dict(zip(coords, plain[0])))
    inertia = {q: sp.diff(kinetic, qd, 2) for q, qd in zip(coords, plain[1])}
    rng = __import__("random").Random(0)
    point = {s: sp.Float(rng.uniform(0.1, 0.3)) for s in (*plain[0], *plain[1])}
    values = {p: sp.Float(par.default) for p, par in spec.parameters.items()}

    def value(expr, kinds, scale):
        at = {
            p: v * scale ** _length_power(par.unit)
            for (p, v), par in zip(values.items(), spec.parameters.values())
        }
        at |= {
            s: v * (scale if not kinds.get(q, True) else 1)
            for q, (s, v) in zip(coords, list(point.items())[: len(coords)])
        }
        at |= {s: v * scale for s, v in list(point.items())[len(coords) :]}
        return float(expr.xreplace(at).evalf())

    kinds: dict = {}
    while True:
        new = {}
        for (q, m), s in zip(inertia.items(), plain[0]):
            if (
                q in kinds
                or m == 0
                or any(m.has(o) for c, o in zip(coords, plain[0]) if c not in kinds and o != s)
            ):
                continue
            try:
                ratio = value(m, kinds, 2.0) / value(m, kinds, 1.0)
            except (TypeError, ValueError, ZeroDivisionError):  # a function sympy cannot evaluate
                inertia[q] = sp.S.Zero
                continue
            new[q] = abs(ratio - 4.0) < abs(ratio - 1.0)
        if not new:
            break
        kinds.update(new)
    exprs = [spec.kinetic, spec.potential, *spec.forces.values(), *spec.constraints]
    trig = (sp.sin, sp.cos, sp.tan, sp.cot, sp.sec, sp.csc)
    for q in coords:
        if q not in kinds:
            kinds[q] = any(f.args[0].has(q) for e in exprs for f in sp.sympify(e).atoms(*trig))
    return kinds


def spec_time():
    from dynamics.spec import t

    return t


def input_units(task: Task) -> dict[str, str]:
    """{input: 'N*m' or 'N'} derived from the model: an input whose generalised force on
    some coordinate has a dimensionless coefficient (Q = u, -u, u cos q, ...) is a torque
    where that coordinate is an angle and a force where it is a length; inputs with no
    such coordinate (or a model given as a compiled System) are left out."""
    if isinstance(task.model, str):  # a registered model: kept on disk by its key
        return dict(_stored_units(task.model))
    try:
        return dict(_units(task.model))
    except TypeError:  # a model object that cannot be a cache key
        return dict(_units.__wrapped__(task.model))


@functools.lru_cache(maxsize=64)
def _stored_units(name: str) -> tuple[tuple[str, str], ...]:
    """`_units(name)` read from the model cache's folder (docs/), keyed by the model's key
    and this module's source: deriving them reads T and every generalised force (seconds
    for the bicycle)."""
    import hashlib
    import json

    import dynamics
    from dynamics.cache import cache_dir

    key = hashlib.sha256((dynamics.get_model(name).key + _SOURCE).encode()).hexdigest()
    path = cache_dir() / "docs" / f"units_{name}_{key[:24]}.json"
    try:
        return tuple(tuple(pair) for pair in json.loads(path.read_text(encoding="utf-8")))
    except (OSError, ValueError, TypeError):
        units = _units(name)
        write_atomic(path, json.dumps(units))
        return units


@functools.lru_cache(maxsize=64)
def _units(model) -> tuple[tuple[str, str], ...]:
    import sympy as sp

    import dynamics

    if isinstance(model, str):
        model = dynamics.get_model(model)
    elif callable(model) and not isinstance(model, dynamics.Model):
        model = dynamics.Model(model)
    spec = getattr(model, "spec", None)
    if spec is None:
        return ()
    parameters = set(spec.parameters)
    angle = coordinate_kinds(spec)
    units = {}
    for u in spec.inputs:
        for q, force in spec.forces.items():
            c = sp.diff(sp.sympify(force), u)
            if c != 0 and not (c.free_symbols & parameters):
                units[str(u)] = "N*m" if angle.get(q, True) else "N"
                break
    return tuple(units.items())


def tables(plant: Plant) -> str:
    """The generated sections of the env docstring, for a built plant."""
    task = plant.task
    prose = (
        f"`Box(-1, 1, ({len(task.actuated)},), float32)`; action -1 and 1 are the input's "
        "limits (`max_input`, overridable when the env is made). Actions outside [-1, 1] are "
        "clipped; NaN or inf actions raise ValueError, complex ones TypeError."
    )
    symmetric = bool((plant.input_low == -plant.input_high).all())
    units = input_units(task)
    lines = ["## Action Space", *textwrap.wrap(prose, 88), ""]
    if symmetric:
        lines += ["| Num | Input | Limit | Unit |", "|-----|-------|-------|------|"]
        for i, (name, limit) in enumerate(zip(task.actuated, plant.input_high)):
            lines.append(f"| {i} | {name} | {limit:.4g} | {units.get(name, '')} |")
    else:
        lines += ["| Num | Input | Min | Max | Unit |", "|-----|-------|-----|-----|------|"]
        for i, (name, lo, hi) in enumerate(zip(task.actuated, plant.input_low, plant.input_high)):
            lines.append(f"| {i} | {name} | {lo:.4g} | {hi:.4g} | {units.get(name, '')} |")
    lines += [
        "",
        "## Observation Space",
        f"`Box(low, high, ({plant.obs_size},), float32)`:",
        "",
        "| Num | Observation | Min | Max | Unit |",
        "|-----|-------------|-----|-----|------|",
    ]
    for i, (label, lo, hi, unit) in enumerate(plant.columns):
        lines.append(f"| {i} | {cell(label)} | {lo:.4g} | {hi:.4g} | {cell(unit)} |")
    lines += ["", "## Reward terms", "", "| Term | Min | Max | Meaning |", "|---|---|---|---|"]
    for term, lo, hi in zip(task.terms, plant.term_low, plant.term_high):
        lines.append(f"| {cell(term.name)} | {lo:.4g} | {hi:.4g} | {cell(term.doc)} |")
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


def current_task(module) -> Task:
    """The task of the current version (`envs.tasks.CURRENT`) among the module's tasks: the
    one its docstring describes (older versions are documented by their own variable's
    docstring, see the site's generator)."""
    mine = [v for v in vars(module).values() if isinstance(v, Task)]
    current = tasks.CURRENT.values()
    return next((t for t in current if any(t is m for m in mine)), module.TASK)


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
    new_doc = document(doc, current_task(module))
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
