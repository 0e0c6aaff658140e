"""Task functions read their inputs by name: `x.theta1`, `a.M2`, `goal.theta1_star`, `p.m2`.

A task whose reward terms carry their own functions (`Term(..., fn=...)`) is *named*: each
of its functions takes `(x, a, goal, p)` where `x` holds the columns of the rows (the
state components, then the declared model outputs), `a` the clipped actions by actuated
input, `goal` the goal components, each a namedtuple of (N,) arrays, and `p` the parameters
and constants (a record, `p.m2`). A goal component's field is its name made an identifier:
`*` becomes `_star` ("theta1*" -> `goal.theta1_star`).

The namedtuple classes live in this module under names that hash their fields, so numba's
on-disk cache, which pickles argument types by reference, finds them in a new process.
"""

from __future__ import annotations

import hashlib
import keyword
import re
from collections import namedtuple

import numpy as np


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
