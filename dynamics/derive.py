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


class _Lagrangian:
    """A spec's Lagrangian L = T - V, given forces and momenta p_s = dL/dqdot_s in plain
    symbols, the forms the code is derived from: q0.. (Q), qd0.. (Qd), qdd0.. (Qdd) for the
    coordinates, Dummies (P, Pd, Pdd) for the prescribed ones, which `on_schedule` replaces
    by their motion p = f(t) and its rates; coordinates, rates, forces and momenta list the
    prescribed coordinates after the free ones."""

    def __init__(self, spec: ModelSpec):
        q, prescribed = list(spec.coordinates), list(spec.prescribed)
        n, m = len(q), len(spec.constraints)
        self.spec = spec
        self.Q, self.Qd, self.Qdd = (sp.symbols(f"{s}0:{n}") for s in ("q", "qd", "qdd"))
        self.P = [sp.Dummy(f"{c.name}") for c in prescribed]
        self.Pd = [sp.Dummy(f"{c.name}_d") for c in prescribed]
        self.Pdd = [sp.Dummy(f"{c.name}_dd") for c in prescribed]
        self.lam = sp.symbols(f"lam0:{m}")
        plain = {t: sp.Symbol("t")}
        plain |= {u: sp.Symbol(f"u{j}") for j, u in enumerate(spec.inputs)}
        plain |= {s: sp.Symbol(f"p{k}") for k, s in enumerate(spec.parameters)}
        plain |= dict(zip(_multipliers(spec), self.lam))  # outputs may use the multipliers
        self.plain, self.t = plain, plain[t]
        # dynamicsymbols -> plain symbols, the highest derivative first (msubs leaves the
        # coordinate inside a Derivative alone, so the order only matters for clarity)
        self.to_plain = {}
        levels = ((2, (self.Qdd, self.Pdd)), (1, (self.Qd, self.Pd)), (0, (self.Q, self.P)))
        for level, names in levels:
            for coords, syms in zip((q, prescribed), names):
                self.to_plain |= {c.diff(t, level) if level else c: s for c, s in zip(coords, syms)}
        self.motion = {}  # the prescribed motion p = f(t), in plain symbols
        for c, s, sd, sdd in zip(prescribed, self.P, self.Pd, self.Pdd):
            f = self.convert(spec.prescribed[c])
            fd = _diff(f, self.t)
            self.motion |= {s: f, sd: fd, sdd: _diff(fd, self.t)}
        self.coords, self.rates = list(self.Q) + self.P, list(self.Qd) + self.Pd
        self.accels = list(self.Qdd) + self.Pdd
        self.L = self.convert(spec.kinetic) - self.convert(spec.potential)
        self.forces = [self.convert(spec.forces.get(c, 0)) for c in q + prescribed]
        self.momenta = [_compact(_diff(self.L, r)) for r in self.rates]

    def convert(self, expr) -> sp.Expr:
        """`expr` (in dynamicsymbols and the spec's symbols) in plain symbols."""
        return me.msubs(sp.sympify(expr), self.to_plain).xreplace(self.plain)

    def on_schedule(self, expr) -> sp.Expr:
        """`expr` with the prescribed coordinates and their rates replaced by f(t)."""
        return expr.xreplace(self.motion) if self.motion else expr

    def lagrange_rest(self, s: int) -> sp.Expr:
        """d/dt(p_s) without the terms in accelerations, - dL/dq_s - Q_s."""
        momentum, T_ = self.momenta[s], self.t
        terms = [_diff(momentum, c) * r for c, r in zip(self.coords, self.rates)]
        terms += [_diff(momentum, T_), -_diff(self.L, self.coords[s]), -self.forces[s]]
        return sp.Add(*terms)


def _mass_and_forcing(g: _Lagrangian) -> tuple[sp.Matrix, sp.Matrix]:
    """M_sk = dp_s/dqdot_k (half of it formed) and F_s = -(the rest of equation s), with
    the prescribed accelerations' terms moved into F."""
    n = len(g.Q)
    mass = sp.zeros(n, n)
    for s in range(n):
        for k in range(s, n):
            mass[s, k] = mass[k, s] = _compact(g.on_schedule(_diff(g.momenta[s], g.Qd[k])))
    forcing = sp.zeros(n, 1)
    for s in range(n):
        driven = [_diff(g.momenta[s], pd) * pdd for pd, pdd in zip(g.Pd, g.Pdd)]
        forcing[s] = _compact(g.on_schedule(-sp.Add(g.lagrange_rest(s), *driven)))
    return mass, forcing


def _constraint_forms(g: _Lagrangian) -> tuple[sp.Matrix, sp.Matrix, sp.Matrix]:
    """(B, b, gamma) of the constraints B qdot + b = 0 and of their rate B qddot = gamma."""
    n, m = len(g.Q), len(g.spec.constraints)
    constraints = [_compact(g.on_schedule(g.convert(c))) for c in g.spec.constraints]
    B = sp.Matrix(m, n, lambda r, k: _diff(constraints[r], g.Qd[k]))
    if any(set(g.Qd) & e.free_symbols for e in B):
        raise ValueError(PFAFFIAN)
    bias = sp.Matrix([c.xreplace({r: 0 for r in g.Qd}) for c in constraints])
    gamma = sp.zeros(m, 1)
    for r in range(m):
        c = constraints[r]  # B qdot + b, whose rate without the accelerations is -gamma
        rate = [_diff(c, a) * ad for a, ad in zip(g.Q, g.Qd)]
        gamma[r] = _compact(-sp.Add(*rate, _diff(c, g.t)))
    return (B if m else sp.zeros(0, n)), (bias if m else sp.zeros(0, 1)), gamma


def _power_and_outputs(g: _Lagrangian) -> tuple[sp.Expr, dict]:
    """The power of the given forces and of the drives of the prescribed coordinates (not
    yet compacted), and the outputs: each drive's reaction, then the spec's outputs."""
    n = len(g.Q)
    power = sp.Add(*[g.on_schedule(g.forces[s]) * g.Qd[s] for s in range(n)])
    outputs = {}
    for j, c in enumerate(g.spec.prescribed):
        # the drive supplies the reaction; given forces on p also work as p follows f(t)
        s = n + j
        accel = [_diff(g.momenta[s], r) * a for r, a in zip(g.rates, g.accels)]
        reaction = _compact(g.on_schedule(sp.Add(g.lagrange_rest(s), *accel)))
        outputs[f"reaction_{c.name}"] = reaction
        power += (reaction + g.on_schedule(g.forces[s])) * g.motion[g.Pd[j]]
    for name, expr in g.spec.outputs.items():
        outputs[name] = _compact(g.on_schedule(g.convert(expr)))
    return power, outputs


def _point_forces(g: _Lagrangian) -> dict:
    """Point name -> the generalised forces (n) of a force (f0, f1[, f2]) at the point,
    by its virtual work."""
    q = list(g.spec.coordinates)
    force = sp.symbols("f0:3")
    points = {}
    for name, v in g.spec.points.items():
        Q_point = generalized_forces(q, [(v, sp.Matrix(force[: len(v)]))])
        points[name] = [_compact(g.on_schedule(g.convert(Q_point[c]))) for c in q]
    return points


def derive(spec: ModelSpec) -> Derived:
    """Form Lagrange's equations of `spec`: M, F, B, b, gamma, T, V, the power and the
    outputs in plain symbols (see the module docstring)."""
    g = _Lagrangian(spec)
    mass, forcing = _mass_and_forcing(g)
    B, bias, gamma = _constraint_forms(g)
    power, outputs = _power_and_outputs(g)
    points = _point_forces(g)
    code = CodeForms(
        mass=mass,
        forcing=forcing,
        constraint_matrix=B,
        constraint_bias=bias,
        constraint_accel=gamma,
        kinetic=_compact(g.on_schedule(g.convert(spec.kinetic))),
        potential=_compact(g.on_schedule(g.convert(spec.potential))),
        power=_compact(power),
        outputs=outputs,
        x=tuple(g.Q) + tuple(g.Qd),
        z=tuple(g.Qdd) + tuple(g.lam),
        u=tuple(g.plain[u] for u in spec.inputs),
        p=tuple(g.plain[s] for s in spec.parameters),
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
