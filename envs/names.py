"""Task functions read their inputs by name: `x.theta1`, `a.M2`, `goal.theta1_star`, `p.m2`.

A task whose reward terms carry their own functions (`Term(..., fn=...)`) is *named*: each
of its functions takes `(x, a, goal, p)` where `x` holds the columns of the rows (the
state components, then the declared model outputs), `a` the clipped actions by actuated
input, `goal` the goal components, each a namedtuple of (N,) arrays, and `p` the parameters
and constants (a record, `p.m2`). A goal component's field is its name made an identifier:
`*` becomes `_star` ("theta1*" -> `goal.theta1_star`).

The `start` and `operating_point` functions read and return names too (see
`operating_state` and `start_values` below; their former forms of arrays keep working with a
DeprecationWarning when the env is made).

The namedtuple classes live in this module under names that hash their fields, so numba's
on-disk cache, which pickles argument types by reference, finds them in a new process.
"""

from __future__ import annotations

import hashlib
import inspect
import keyword
import re
import weakref
from collections import namedtuple
from collections.abc import Mapping

import numpy as np

from dynamics.checks import did_you_mean


def identifier(name: str) -> str:
    """`name` as a Python identifier: '*' -> '_star', other invalid characters -> '_'."""
    ident = re.sub(r"\W", "_", name.replace("*", "_star"))
    if not ident or ident[0].isdigit() or keyword.iskeyword(ident):
        ident = "_" + ident
    return ident


def record_type(kind: str, names) -> type:
    """The namedtuple class of `kind` ('Rows', 'Actions', 'Goal') with fields `names`
    (made identifiers), one per distinct field list."""
    fields = tuple(identifier(n) for n in names)
    if len(set(fields)) != len(fields):
        raise ValueError(f"{kind} names {list(names)} collide as identifiers {list(fields)}.")
    digest = hashlib.sha256(repr(fields).encode()).hexdigest()[:12]
    cls_name = f"{kind}_{digest}"
    cls = globals().get(cls_name)
    if cls is None:
        cls = namedtuple(cls_name, fields)
        cls.__module__ = __name__
        globals()[cls_name] = cls
    return cls


def columns(cls: type, rows: np.ndarray):
    """An instance of `cls` whose fields are the columns of `rows` (N, k): views."""
    return cls(*(rows[:, i] for i in range(rows.shape[1])))


def caller(fn, rows_cls: type, actions_cls: type, goal_cls: type):
    """`fn(x, a, goal, p)` on named inputs, called with the runtime's positional arrays."""

    def call(x, a, g, p):
        return fn(columns(rows_cls, x), columns(actions_cls, a), columns(goal_cls, g), p)

    call.__qualname__ = getattr(fn, "__qualname__", "call")
    call.named = fn
    return call


# ---- the start and operating-point functions ------------------------------------------------
# A start function keeps its inputs `(rng, p)` (p was always the record) and returns names:
# `({state: value}, {goal: value})`. Its form is told by what it returns, a dict against the
# former arrays, which cannot be confused and needs no marking. An operating-point function
# takes `(x, goal, p)`, or `(x, goal, p, system)` where it needs the compiled model, and
# returns {state: value or (N,) array}. Both forms take three inputs, so its form is told by
# its parameter names: `x, goal, p` in that order, the names every task function uses (the
# former form was documented as `(g, x, system)`); a decorator would burden every new
# function for the sake of the old ones. Unnamed states are 0 in both; unnamed goal
# components of a start are drawn uniformly over their ranges.
FORMER_START = (
    "Task {task!r}: `start` function {fn} returns arrays (x, g), a former form; return names "
    "instead: ({{state: value}}, {{goal: value}}), unnamed states 0."
)
FORMER_OPERATING_POINT = (
    "Task {task!r}: `operating_point` function {fn} takes the former form (g, x, system) of "
    "arrays; name its parameters (x, goal, p), or (x, goal, p, system), read x.theta, "
    "goal.theta_star, p.m, and return {{state: value}}, unnamed states 0."
)


def label(fn) -> str:
    """A function's name for messages ('<lambda>' and callable objects included)."""
    return getattr(fn, "__qualname__", None) or type(fn).__name__


def named_operating_point(fn) -> bool:
    """Whether an operating-point function takes the named form `(x, goal, p[, system])`,
    told by its parameter names (see above)."""
    return _operating_point_form(fn)[0]


def _operating_point_form(fn) -> tuple[bool, bool]:
    """(named form, takes the system): read from the signature once per function (policies
    ask for the operating point at every step)."""
    try:
        return _FORMS[fn]
    except (KeyError, TypeError):  # not seen yet, or unhashable (read every time)
        pass
    try:
        params = list(inspect.signature(fn).parameters)
    except (TypeError, ValueError):  # no signature to read: the former form
        params = []
    form = (params[:3] == ["x", "goal", "p"], len(params) > 3)
    try:
        _FORMS[fn] = form
    except TypeError:
        pass
    return form


_FORMS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def state_rows(values, names, n: int, where: str) -> np.ndarray:
    """{state name (or its identifier): value or (n,) array} (a namedtuple too) as rows
    (n, len(names)), unnamed states 0."""
    if hasattr(values, "_asdict"):
        values = values._asdict()
    if not isinstance(values, Mapping):
        raise TypeError(
            f"{where} must return {{state name: value}} (unnamed states 0), "
            f"got {type(values).__name__}."
        )
    index = {identifier(k): i for i, k in enumerate(names)}
    rows = np.zeros((n, len(names)))
    for key, value in values.items():
        i = index.get(identifier(str(key)))
        if i is None:
            raise ValueError(
                f"{where} names unknown state {key!r}.{did_you_mean(str(key), names)} "
                f"Known: {', '.join(names)}."
            )
        rows[:, i] = value
    return rows


def operating_state(fn, plant, g: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The rows (N, 2n) an operating-point function gives for goals g and states x, in
    either form; the named one reads read-only copies."""
    named, wants_system = _operating_point_form(fn)
    if not named:
        return np.asarray(fn(g, x, plant.system), dtype=np.float64).reshape(len(g), -1)
    rows = [np.array(a, dtype=np.float64) for a in (x, g)]
    for a in rows:
        a.setflags(write=False)
    x_rec = columns(record_type("Rows", plant.state_names), rows[0])
    goal = columns(record_type("Goal", plant.goal_names), rows[1])
    extra = (plant.system,) if wants_system else ()
    out = fn(x_rec, goal, plant.p, *extra)
    where = f"Task {plant.task.name!r}: `operating_point` function {label(fn)}"
    return state_rows(out, plant.state_names, len(g), where)


def start_values(plant, out, rng) -> tuple[np.ndarray, np.ndarray, bool]:
    """(x, g, named) from what a start function returned, in either form; goal components
    the named form leaves out drawn uniformly over their ranges with `rng`."""
    if not (isinstance(out, tuple) and len(out) == 2 and isinstance(out[0], Mapping)):
        x, g = out
        return np.asarray(x, dtype=np.float64), np.asarray(g, dtype=np.float64), False
    where = f"Task {plant.task.name!r}: `start` function {label(plant.task.start)}"
    x = state_rows(out[0], plant.state_names, 1, where)[0]
    given = out[1] if out[1] is not None else {}
    if not isinstance(given, Mapping):
        raise TypeError(f"{where} must return a goal {{name: value}}, got {type(given).__name__}.")
    goals = {identifier(k): k for k in plant.goal_names}
    unknown = [k for k in given if identifier(str(k)) not in goals]
    if unknown:
        raise ValueError(
            f"{where} names unknown goal component {unknown[0]!r}."
            f"{did_you_mean(str(unknown[0]), plant.goal_names)} "
            f"Known: {', '.join(plant.goal_names) or 'none'}."
        )
    values = {identifier(str(k)): v for k, v in given.items()}
    g = np.array(
        [
            values[identifier(k)] if identifier(k) in values else rng.uniform(lo, hi)
            for k, lo, hi in zip(plant.goal_names, plant.goal_low, plant.goal_high)
        ],
        dtype=np.float64,
    )
    return x, g, True


_ARGUMENTS = {"Rows": "x", "Actions": "a", "Goal": "goal"}
"""The argument of a task function that each record type of `envs.names` is."""


def missing_field(exc: Exception, p=None) -> str | None:
    """A task function's misspelt name, in one line: which input (x, a, goal or p) lacks
    it, a suggestion and the names it has; None for any other error. (Python names the
    runtime's record class, e.g. 'Rows_97f252393812', which the user never wrote.)"""
    found = re.search(r"has no attribute '(\w+)'", str(exc))
    if not isinstance(exc, AttributeError) or not found:
        return None
    obj = getattr(exc, "obj", None)
    fields = getattr(obj, "_fields", None)
    if fields is not None:
        which = _ARGUMENTS.get(type(obj).__name__.split("_")[0], type(obj).__name__)
    elif p is not None and (obj is None or isinstance(obj, np.record)):
        which, fields = "p", p.dtype.names  # (a numpy record's error names no object)
    else:
        return None
    name = found[1]
    return (
        f"{which} has no name {name!r}.{did_you_mean(name, fields)} "
        f"{which}'s names: {', '.join(fields) or 'none'}."
    )
