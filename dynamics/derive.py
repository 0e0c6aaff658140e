"""Lagrange's equations from a `ModelSpec`, with multipliers for Pfaffian constraints.

For each coordinate q_s (eq. 7.36, the book's sign):

    d/dt(dL/dqdot_s) - dL/dq_s - Q_s + sum_r lambda_r B_rs = 0

The equations are linear in the accelerations, so they are split into a mass matrix and a
forcing vector, M(q, t) qddot + B^T lambda = F(q, qdot, t, u), never inverted symbolically.
The constraints B qdot + b = 0 are differentiated once: B qddot = gamma(q, qdot, t).

Two forms of the same equations. `derive` writes the code forms (`Derived.code`) in plain
symbols, term by term and without simplifying: with p_s = dL/dqdot_s,

    M_sk = dp_s/dqdot_k (the Hessian of L in the rates, symmetric: half of it is formed),
    F_s = Q_s + dL/dq_s - sum_k dp_s/dq_k qdot_k - dp_s/dt,

so nothing is expanded and no expression is formed twice; the generated code's common
subexpressions do the rest. The display forms (`Derived.equations`, `.mass`, `.kinetic`...,
what `python -m dynamics show` and docs/models.md print and the book's tests compare) are the
same equations in dynamicsymbols, expanded and simplified entry by entry: `sympy.simplify`
costs minutes for a chain of seven links, so they are formed only when first asked for.

The derivation is written out here rather than through `LagrangesMethod`, which takes forces
as (point, vector) pairs: the book gives generalised forces Q_s directly (section 7.1,
step 3). The tests cross-check it against `LagrangesMethod` on the arm.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import sympy as sp
import sympy.physics.mechanics as me

from .calculus import compact as _compact
from .calculus import diff as _diff
from .spec import ModelSpec, generalized_forces, t

PFAFFIAN = "constraints must be linear in the coordinate rates (Pfaffian form)."


@dataclass(frozen=True)
class CodeForms:
    """The equations as code is generated from them, in plain symbols: coordinates q0..,
    rates qd0.., accelerations qdd0.., multipliers lam0.., inputs u0.., parameters p0..
    (in the order of the spec) and time t. Entries are unsimplified but exact."""

    mass: sp.Matrix  # M, n x n
    forcing: sp.Matrix  # F, n x 1
    constraint_matrix: sp.Matrix  # B, m x n
    constraint_bias: sp.Matrix  # b, m x 1
    constraint_accel: sp.Matrix  # gamma, m x 1
    kinetic: sp.Expr
    potential: sp.Expr
    power: sp.Expr
    outputs: dict  # name -> expression (may contain qdd and lam)
    x: tuple  # (q0.., qd0..)
    z: tuple  # (qdd0.., lam0..)
    u: tuple  # (u0..)
    p: tuple  # (p0..)
    # name -> the generalised forces (n) of a force (f0, f1[, f2]) at that point
    points: dict = field(default_factory=dict)


class Derived:
    """What is derived from a spec: `code` (plain symbols, for code generation) at once, and
    the display forms (dynamicsymbols, simplified) when first read."""

    def __init__(self, spec: ModelSpec, code: CodeForms, multipliers: tuple):
        self.spec = spec
        self.code = code
        self.multipliers = multipliers  # lambda_r symbols of the display forms

    @cached_property
    def _display(self) -> dict:
        return _display_forms(self.spec)

    # the display forms: each entry simplified (slow for large systems; never on the hot path)
    def _form(key: str, doc: str):  # a property factory, run while the class is made
        return property(lambda self: self._display[key], doc=doc)

    equations = _form("equations", "sympy Matrix, each entry = 0 (with qddot and lambda)")
    mass = _form("mass", "M, n x n")
    forcing = _form("forcing", "F, n x 1")
    constraint_matrix = _form("constraint_matrix", "B, m x n")
    constraint_bias = _form("constraint_bias", "b, m x 1")
    constraint_accel = _form("constraint_accel", "gamma, m x 1")
    kinetic = _form("kinetic", "T")
    potential = _form("potential", "V")
    power = _form("power", "power of the given forces and of the prescribed-motion reactions")
    outputs = _form("outputs", "name -> expression (may contain qddot and lambda)")
    del _form


def _multipliers(spec: ModelSpec) -> tuple:
    return tuple(sp.Symbol(f"lambda{r + 1}") for r in range(len(spec.constraints)))


def derive(spec: ModelSpec) -> Derived:
    """Form Lagrange's equations of `spec`: M, F, B, b, gamma, T, V, the power and the
    outputs in plain symbols (see the module docstring)."""
    q = list(spec.coordinates)
    n, m = len(q), len(spec.constraints)
    prescribed = list(spec.prescribed)
    Q, Qd, Qdd = (sp.symbols(f"{s}0:{n}") for s in ("q", "qd", "qdd"))
    P = [sp.Dummy(f"{c.name}") for c in prescribed]
    Pd = [sp.Dummy(f"{c.name}_d") for c in prescribed]
    Pdd = [sp.Dummy(f"{c.name}_dd") for c in prescribed]
    lam = sp.symbols(f"lam0:{m}")
    plain = {t: sp.Symbol("t")}
    plain |= {u: sp.Symbol(f"u{j}") for j, u in enumerate(spec.inputs)}
    plain |= {s: sp.Symbol(f"p{k}") for k, s in enumerate(spec.parameters)}
    plain |= dict(zip(_multipliers(spec), lam))  # outputs may use the multipliers
    T_ = plain[t]

    # dynamicsymbols -> plain symbols, the highest derivative first (msubs leaves the
    # coordinate inside a Derivative alone, so the order only matters for clarity)
    to_plain = {}
    for level, names in ((2, (Qdd, Pdd)), (1, (Qd, Pd)), (0, (Q, P))):
        for coords, syms in zip((q, prescribed), names):
            to_plain |= {c.diff(t, level) if level else c: s for c, s in zip(coords, syms)}

    def convert(expr):
        return me.msubs(sp.sympify(expr), to_plain).xreplace(plain)

    # the prescribed motion p = f(t), in plain symbols, and its substitution
    motion = {}
    for c, s, sd, sdd in zip(prescribed, P, Pd, Pdd):
        f = convert(spec.prescribed[c])
        fd = _diff(f, T_)
        motion |= {s: f, sd: fd, sdd: _diff(fd, T_)}

    def on_schedule(expr):
        return expr.xreplace(motion) if motion else expr

    coords, rates, accels = list(Q) + P, list(Qd) + Pd, list(Qdd) + Pdd
    L = convert(spec.kinetic) - convert(spec.potential)
    forces = [convert(spec.forces.get(c, 0)) for c in q + prescribed]
    momenta = [_compact(_diff(L, r)) for r in rates]

    def lagrange_rest(s):
        """d/dt(p_s) without the terms in accelerations, - dL/dq_s - Q_s."""
        terms = [_diff(momenta[s], c) * r for c, r in zip(coords, rates)]
        terms += [_diff(momenta[s], T_), -_diff(L, coords[s]), -forces[s]]
        return sp.Add(*terms)

    mass = sp.zeros(n, n)
    for s in range(n):
        for k in range(s, n):
            mass[s, k] = mass[k, s] = _compact(on_schedule(_diff(momenta[s], Qd[k])))
    forcing = sp.zeros(n, 1)
    for s in range(n):
        driven = [_diff(momenta[s], pd) * pdd for pd, pdd in zip(Pd, Pdd)]
        forcing[s] = _compact(on_schedule(-sp.Add(lagrange_rest(s), *driven)))

    constraints = [_compact(on_schedule(convert(c))) for c in spec.constraints]
    B = sp.Matrix(m, n, lambda r, k: _diff(constraints[r], Qd[k]))
    if any(set(Qd) & e.free_symbols for e in B):
        raise ValueError(PFAFFIAN)
    bias = sp.Matrix([c.xreplace({r: 0 for r in Qd}) for c in constraints])
    gamma = sp.zeros(m, 1)
    for r in range(m):
        c = constraints[r]  # B qdot + b, whose rate without the accelerations is -gamma
        gamma[r] = _compact(-sp.Add(*[_diff(c, a) * ad for a, ad in zip(Q, Qd)], _diff(c, T_)))

    power = sp.Add(*[on_schedule(forces[s]) * Qd[s] for s in range(n)])
    outputs = {}
    for j, c in enumerate(prescribed):
        # the drive supplies the reaction; given forces on p also work as p follows f(t)
        s = n + j
        accel = [_diff(momenta[s], r) * a for r, a in zip(rates, accels)]
        reaction = _compact(on_schedule(sp.Add(lagrange_rest(s), *accel)))
        outputs[f"reaction_{c.name}"] = reaction
        power += (reaction + on_schedule(forces[s])) * motion[Pd[j]]
    for name, expr in spec.outputs.items():
        outputs[name] = _compact(on_schedule(convert(expr)))

    force = sp.symbols("f0:3")
    points = {}
    for name, v in spec.points.items():  # virtual work of a force at the point
        Q_point = generalized_forces(q, [(v, sp.Matrix(force[: len(v)]))])
        points[name] = [_compact(on_schedule(convert(Q_point[c]))) for c in q]

    code = CodeForms(
        mass=mass,
        forcing=forcing,
        constraint_matrix=B if m else sp.zeros(0, n),
        constraint_bias=bias if m else sp.zeros(0, 1),
        constraint_accel=gamma,
        kinetic=_compact(on_schedule(convert(spec.kinetic))),
        potential=_compact(on_schedule(convert(spec.potential))),
        power=_compact(power),
        outputs=outputs,
        x=tuple(Q) + tuple(Qd),
        z=tuple(Qdd) + tuple(lam),
        u=tuple(plain[u] for u in spec.inputs),
        p=tuple(plain[s] for s in spec.parameters),
        points=points,
    )
    return Derived(spec, code, _multipliers(spec))


# ---- display forms ---------------------------------------------------------------------------
def _prescribed_substitutions(prescribed) -> dict:
    """{p'': f'', p': f', p: f} for each prescribed coordinate, highest derivative first."""
    subs = {}
    for p, f in prescribed.items():
        subs[p.diff(t, 2)] = f.diff(t, 2)
    for p, f in prescribed.items():
        subs[p.diff(t)] = f.diff(t)
    for p, f in prescribed.items():
        subs[p] = f
    return subs


def _pfaffian(constraints, q) -> tuple[sp.Matrix, sp.Matrix]:
    rates = [qi.diff(t) for qi in q]
    B = sp.Matrix([[sp.diff(c, qd) for qd in rates] for c in constraints])
    if any(d in B.atoms(sp.Derivative) for d in rates):
        raise ValueError(PFAFFIAN)
    b = sp.Matrix([c for c in constraints]) - B * sp.Matrix(rates)
    b = b.applyfunc(sp.expand).applyfunc(sp.simplify)
    if any(d in b.atoms(sp.Derivative) for d in rates):
        raise ValueError(PFAFFIAN)
    return B.applyfunc(sp.simplify), b


def _display_forms(spec: ModelSpec) -> dict:
    """The equations in dynamicsymbols, each entry expanded and simplified for reading."""
    q = list(spec.coordinates)
    qd = [qi.diff(t) for qi in q]
    qdd = [qi.diff(t, 2) for qi in q]
    full = q + list(spec.prescribed)
    sub_p = _prescribed_substitutions(spec.prescribed)

    L = spec.kinetic - spec.potential
    forces = {c: sp.sympify(spec.forces.get(c, 0)) for c in full}
    lagrange = {c: sp.diff(sp.diff(L, c.diff(t)), t) - sp.diff(L, c) - forces[c] for c in full}
    lagrange = {c: sp.expand(me.msubs(e, sub_p)) for c, e in lagrange.items()}

    constraints = [sp.expand(me.msubs(sp.sympify(c), sub_p)) for c in spec.constraints]
    m = len(constraints)
    lam = _multipliers(spec)
    if m:
        B, b = _pfaffian(constraints, q)
    else:
        B, b = sp.zeros(0, len(q)), sp.zeros(0, 1)

    eqs = sp.Matrix([lagrange[c] for c in q])
    if m:
        eqs = eqs + B.T * sp.Matrix(lam)
    mass = eqs.jacobian(qdd).applyfunc(sp.simplify)
    zero_acc = {a: 0 for a in qdd} | {lr: 0 for lr in lam}
    forcing = (-eqs.subs(zero_acc)).applyfunc(sp.simplify)

    if m:
        residual = B * sp.Matrix(qd) + b
        gamma = (-residual.diff(t).subs({a: 0 for a in qdd})).applyfunc(sp.simplify)
    else:
        gamma = sp.zeros(0, 1)

    power = sum((me.msubs(forces[c], sub_p) * c.diff(t) for c in q), sp.S.Zero)
    outputs = {}
    for p, f in spec.prescribed.items():
        outputs[f"reaction_{p.name}"] = sp.simplify(lagrange[p])
        power += (lagrange[p] + me.msubs(forces[p], sub_p)) * f.diff(t)
    for name, expr in spec.outputs.items():
        outputs[name] = sp.simplify(me.msubs(sp.sympify(expr), sub_p))

    return dict(
        equations=sp.Matrix([sp.simplify(e) for e in eqs]),
        mass=mass,
        forcing=forcing,
        constraint_matrix=B,
        constraint_bias=b,
        constraint_accel=gamma,
        kinetic=sp.simplify(me.msubs(spec.kinetic, sub_p)),
        potential=sp.simplify(me.msubs(spec.potential, sub_p)),
        power=sp.simplify(power),
        outputs=outputs,
    )
