"""Whether parameter values describe a system that can exist, over one point or a whole box.

A compiled model says what its parameters must satisfy: signs (`Param.positive`,
`Param.nonnegative`), its `conditions` (expressions that must be > 0) and its `bodies`,
whose inertia must be one some mass distribution has: the tensor positive definite and
each principal moment at most the sum of the other two (the triangle inequality; equality
is a flat body, a thin disk's J = 2 I). `problems` lists what a point breaks;
`box_problem` searches a box of values (a randomisation's supports, a benchmark's grid) for
a point that breaks something.

Over a box: each condition and body is evaluated at every corner of the box of the
parameters it reads (found by moving each one alone) and on a 3-point grid across them (or
512 random points where that grid would pass 729 points), the rest at the box's middle;
then at 256 random points of the whole box. A body's test is exact this way: its smallest
eigenvalue and trace - 2 x its largest are concave in the tensor's entries, so over a box
of entries affine in the parameters they are least at a corner.
"""

from __future__ import annotations

import itertools
from types import ModuleType

import numpy as np

FLAT = 1e-9
"""Relative slack of the triangle inequality: a body at equality (a flat one, whose moments
are rounded from m r^2 / 4 and m r^2 / 2) is possible."""


def inertia_problem(entries) -> str | None:
    """Why the tensor of `entries` (xx, xy, xz, yy, yz, zz) is no rigid body's, or None."""
    xx, xy, xz, yy, yz, zz = (float(v) for v in entries)
    J = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    if not np.isfinite(J).all():
        return "has non-finite entries"
    lam = np.linalg.eigvalsh(J)
    scale = max(abs(lam).max(), 1e-300)
    if not lam[0] > FLAT * scale:
        return f"is not positive definite (principal moments {_moments(lam)})"
    if lam[2] > lam[0] + lam[1] + FLAT * scale:
        return (
            f"breaks the triangle inequality (principal moments {_moments(lam)}: the largest "
            "exceeds the sum of the other two)"
        )
    return None


def _moments(lam) -> str:
    return ", ".join(f"{v:.4g}" for v in lam)


def problems(module: ModuleType, p: np.ndarray) -> list[str]:
    """What the parameter vector `p` (in the order of module.PARAMETERS) breaks: the model's
    conditions and its bodies' inertia (signs are checked by `System`)."""
    out = []
    with np.errstate(all="ignore"):
        for statement, value in zip(module.CONDITIONS, module.conditions(p)):
            if not value > 0:
                out.append(f"violate {statement}")
        for (name, _), entries in zip(bodies(module), inertias(module, p)):
            why = inertia_problem(entries)
            if why is not None:
                out.append(f"give body {name!r} an inertia that {why}")
    return out


def bodies(module: ModuleType) -> tuple:
    """((name, parameters it reads), ...) of a generated module (none before bodies)."""
    return getattr(module, "BODIES", ())


def inertias(module: ModuleType, p) -> tuple:
    return module.inertias(p) if bodies(module) else ()


def _checks(module: ModuleType):
    """One function p -> bool (holds) per condition and body, with its label."""
    out = []
    for k, statement in enumerate(module.CONDITIONS):
        out.append((statement, lambda p, k=k: bool(module.conditions(p)[k] > 0)))
    for k, (name, _) in enumerate(bodies(module)):
        out.append(
            (f"body {name!r}", lambda p, k=k: inertia_problem(module.inertias(p)[k]) is None)
        )
    return out


def box_problem(module: ModuleType, nominal: np.ndarray, axes: list) -> str | None:
    """A point of the box that breaks a condition or a body, described, or None.

    nominal: (n_p,) values of the parameters no axis moves. axes: one per independent
    quantity, (label, columns, low values, high values): moving the quantity from its low
    end to its high end moves parameters `columns` from `low` to `high` (affinely: a
    randomised parameter and those drawn with it, or a grid's scale)."""
    if not axes:
        return None
    checks = _checks(module)
    if not checks:
        return None
    rng = np.random.default_rng(0)

    def point(t) -> np.ndarray:
        p = nominal.copy()
        for (_, cols, lo, hi), s in zip(axes, t):
            p[list(cols)] = np.asarray(lo) + s * (np.asarray(hi) - np.asarray(lo))
        return p

    middle = np.full(len(axes), 0.5)
    with np.errstate(all="ignore"):
        for label, holds in checks:
            reads = [i for i in range(len(axes)) if _moves(module, point, middle, i, label)]
            for t in _points(middle, reads, rng):
                if not holds(point(t)):
                    return _describe(label, [axes[i] for i in reads], t[reads])
        for t in rng.uniform(0.0, 1.0, (256, len(axes))):
            for label, holds in checks:
                if not holds(point(t)):
                    return _describe(label, axes, t)
    return None


def _moves(module, point, middle, i, label) -> bool:
    """Whether moving axis i alone (to either end) changes the values of check `label`."""
    values = []
    for s in (0.0, 0.5, 1.0):
        t = middle.copy()
        t[i] = s
        p = point(t)
        if label.startswith("body "):
            k = [f"body {n!r}" for n, _ in bodies(module)].index(label)
            values.append(tuple(module.inertias(p)[k]))
        else:
            values.append(module.conditions(p)[list(module.CONDITIONS).index(label)])
    return len(set(values)) > 1


def _points(middle, reads, rng):
    """Corners of the axes `reads`, then a 3-point grid (or 512 random points) across them."""
    if len(reads) > 16:
        grids = [rng.integers(0, 2, len(reads)) for _ in range(4096)]
    else:
        grids = list(itertools.product((0.0, 1.0), repeat=len(reads)))
    if 3 ** len(reads) <= 729:
        grids += list(itertools.product((0.0, 0.5, 1.0), repeat=len(reads)))
    else:
        grids += list(rng.uniform(0.0, 1.0, (512, len(reads))))
    for g in grids:
        t = middle.copy()
        t[reads] = g
        yield t


def _describe(label: str, axes, t) -> str:
    where = ", ".join(f"{name} at its {_end(s)}" for (name, *_), s in zip(axes, t))
    return f"{label} fails with {where}"


def _end(s: float) -> str:
    return {0.0: "low end", 1.0: "high end", 0.5: "middle"}.get(float(s), f"{s:.2f} of its range")
