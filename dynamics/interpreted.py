"""A model's first points in a process run as Python, not compiled (`INTERPRETED_POINTS`).

The generated kernels' Python functions (`py_func`) evaluate the same arithmetic in the
same order as their compiled code; `run` uses them for a few points while the compiled
kernel is not in use yet, so that an env's checks at make time compile nothing.
"""

from __future__ import annotations

import numpy as np

from . import cache

INTERPRETED_POINTS = 5000
"""While a model's linearisation kernel is not compiled (`_compiled`), its first points in a
process (`System.linearize`, `System.kkt`) run its generated code as plain Python: the same
arithmetic in the same order (the same numbers up to the last bit of a power, which Python
takes from libm's `pow` and numba as products; tests/dynamics/test_linearize.py), without
compiling it. So do `System.accelerations` and `multipliers` of at most `INTERPRETED_ROWS`
rows while their kernel is not compiled: the checks an env runs when it is made (every
input moves something, the operating input) then compile nothing the first step does not
need. A handful of points (an LQR design, the bicycle's benchmark matrices) then
costs milliseconds instead of compiling the Jacobians (the bicycle's 4,500 lines: 40 s of
CPU). A point interpreted costs about 1e-4 of that compilation (two-link arm 0.2 ms
against 1.5 s, the bicycle 3-6 ms against 40 s), so a planner's many linearisations switch
to the compiled kernel after this many, having spent at most about half of it."""

INTERPRETED_ROWS = 64
"""The largest batch of `System.accelerations` that may run as Python (see above)."""

_interpreted_points: dict[str, int] = {}


def _compiled(m) -> bool:
    """True when module m's linearisation kernel is compiled (`cache.compiled`)."""
    return cache.compiled(m.linear_terms)


def accelerations_py(m, t, x, u, p, z) -> None:
    """`accelerations` of module m through the Python functions of its kernels."""
    A = np.empty((m.K, m.K + 1))  # a spare column for solve
    m.kkt.py_func(t, x, u, p, A, z)
    m.solve.py_func(A, z)


def kkt_py(m, t, x, u, p, A, r) -> None:
    m.kkt.py_func(t, x, u, p, A, r)


def linear_terms_py(m, t, x, u, p, A, z, Jx, Ju) -> None:
    """`linear_terms` of module m through the Python functions of its kernels."""
    m.kkt.py_func(t, x, u, p, A, z)
    m.solve.py_func(A, z)
    m.jacobians.py_func(t, x, u, p, z.tolist(), Jx, Ju)
    m.kkt_matrix.py_func(t, x, p, A)


def run(m, p, program, t, x, u, *out, compiled: bool | None = None) -> bool:
    """Run `program` (one of the `*_py` functions here) of model module `m` with
    parameters `p` on one point, while the model's compiled kernel is not in use yet
    (`INTERPRETED_POINTS`; `compiled`: whether it is, by default whether the linearisation
    is): True if it filled `out`, False where Python's arithmetic raised (a division by
    zero, an overflow) and the compiled kernels must give their NaN or inf instead."""
    used = _interpreted_points.get(m.KEY, 0)
    if used >= INTERPRETED_POINTS or (_compiled(m) if compiled is None else compiled):
        return False
    _interpreted_points[m.KEY] = used + 1
    try:
        with np.errstate(all="ignore"):
            program(m, float(t), x.tolist(), u.tolist(), p.tolist(), *out)
    except (ArithmeticError, ValueError):
        return False
    return True
