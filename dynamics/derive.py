"""Lagrange's equations from a `ModelSpec`, with multipliers for Pfaffian constraints.

For each coordinate q_s (eq. 7.36, the book's sign):

    d/dt(dL/dqdot_s) - dL/dq_s - Q_s + sum_r lambda_r B_rs = 0

The equations are linear in the accelerations, so they are split into a mass matrix and a
forcing vector, M(q, t) qddot + B^T lambda = F(q, qdot, t, u), never inverted symbolically.
The constraints B qdot + b = 0 are differentiated once: B qddot = gamma(q, qdot, t).

The derivation is written out here rather than through `LagrangesMethod`, which takes forces
as (point, vector) pairs: the book gives generalised forces Q_s directly (section 7.1,
step 3). The tests cross-check it against `LagrangesMethod` on the arm.
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp
import sympy.physics.mechanics as me

from .spec import ModelSpec, t


@dataclass
class Derived:
    """Symbolic results, in dynamicsymbols (for display) and plain symbols (for code)."""

    spec: ModelSpec
    equations: sp.Matrix  # each = 0, with qddot and lambda symbols
    multipliers: tuple  # lambda_r symbols
    mass: sp.Matrix  # M, n x n
    forcing: sp.Matrix  # F, n x 1
    constraint_matrix: sp.Matrix  # B, m x n
    constraint_bias: sp.Matrix  # b, m x 1
    constraint_accel: sp.Matrix  # gamma, m x 1
    kinetic: sp.Expr
    potential: sp.Expr
    power: sp.Expr  # power of the given forces and of the prescribed-motion reactions
    outputs: dict  # name -> expression (may contain qddot and lambda)


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
        raise ValueError("constraints must be linear in the coordinate rates (Pfaffian form).")
    b = sp.Matrix([c for c in constraints]) - B * sp.Matrix(rates)
    b = b.applyfunc(sp.expand).applyfunc(sp.simplify)
    if any(d in b.atoms(sp.Derivative) for d in rates):
        raise ValueError("constraints must be linear in the coordinate rates (Pfaffian form).")
    return B.applyfunc(sp.simplify), b


def derive(spec: ModelSpec) -> Derived:
    """Form Lagrange's equations of `spec` and split them into M, F, B, b, gamma."""
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
    lam = tuple(sp.Symbol(f"lambda{r + 1}") for r in range(m))
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

    T = sp.simplify(me.msubs(spec.kinetic, sub_p))
    V = sp.simplify(me.msubs(spec.potential, sub_p))
    power = sum((me.msubs(forces[c], sub_p) * c.diff(t) for c in q), sp.S.Zero)
    outputs = {}
    for p, f in spec.prescribed.items():
        # the drive supplies the reaction; given forces on p also work as p follows f(t)
        outputs[f"reaction_{p.name}"] = sp.simplify(lagrange[p])
        power += (lagrange[p] + me.msubs(forces[p], sub_p)) * f.diff(t)
    for name, expr in spec.outputs.items():
        outputs[name] = sp.simplify(me.msubs(sp.sympify(expr), sub_p))

    return Derived(
        spec=spec,
        equations=sp.Matrix([sp.simplify(e) for e in eqs]),
        multipliers=lam,
        mass=mass,
        forcing=forcing,
        constraint_matrix=B,
        constraint_bias=b,
        constraint_accel=gamma,
        kinetic=T,
        potential=V,
        power=sp.simplify(power),
        outputs=outputs,
    )
