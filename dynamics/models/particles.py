"""One particle in 3-space (sections 7.2-7.3, problem 7/1), in several coordinate systems.

Every model here is built the same way, from transformation equations r = (x, y, z)(q):
T = m |dr/dt|^2 / 2, and a force given in Cartesian components becomes generalised forces
Q_s = F . dr/dq_s by virtual work (eq. 6.15, as the book uses it in (7.9) and (7.13)), through
`generalized_forces` with the velocity dr/dt as a Matrix. No generalised force is written by
hand. Unless a model says otherwise, the given force is gravity, m g down the z axis, plus the
inputs Fx, Fy, Fz (N), Cartesian components of any further force.
"""

from __future__ import annotations

import sympy as sp
import sympy.physics.mechanics as me

from ..parse import parse_expression
from ..spec import ModelSpec, Param, generalized_forces, t

_m, _g = sp.symbols("m g", positive=True)
_FORCE = sp.symbols("Fx Fy Fz")
_BASE_PARAMETERS = {
    _m: Param(1.0, "kg", "mass of the particle"),
    _g: Param(9.81, "m/s^2", "gravitational acceleration, along -z (0 switches it off)", False),
}


def cartesian_particle(
    name: str, coordinates, position, doc: str, gravity: bool = True, **spec
) -> ModelSpec:
    """A particle at `position` (x, y, z as functions of `coordinates`) under the Cartesian
    input force (Fx, Fy, Fz) and, if `gravity`, m g along -z. Extra ModelSpec fields pass
    through `spec`; its `parameters` are added to m (and g), its `outputs` to the Cartesian
    position (outputs position_x, position_y, position_z)."""
    r = sp.Matrix(position)
    v = r.diff(t)
    T = _m * (v.T * v)[0, 0] / 2
    V = _m * _g * r[2] if gravity else sp.S.Zero
    Q = generalized_forces(coordinates, [(v, sp.Matrix(_FORCE))])
    for c, extra in spec.pop("forces", {}).items():
        Q[c] = Q[c] + extra
    parameters = {_m: _BASE_PARAMETERS[_m]}
    if gravity:
        parameters[_g] = _BASE_PARAMETERS[_g]
    parameters |= spec.pop("parameters", {})
    outputs = {"position_x": r[0], "position_y": r[1], "position_z": r[2]}
    outputs |= spec.pop("outputs", {})
    return ModelSpec(
        name=name,
        coordinates=tuple(coordinates),
        inputs=_FORCE,
        kinetic=sp.simplify(T),
        potential=V,
        forces=Q,
        parameters=parameters,
        outputs=outputs,
        description=doc,
        **spec,
    )


def particle_cartesian() -> ModelSpec:
    """An unconstrained particle in rectangular coordinates x, y, z (eqs. 7.1-7.4).

    z is up (gravity m g along -z); inputs Fx, Fy, Fz: a further given force, N.
    """
    x, y, z = me.dynamicsymbols("x y z")
    return cartesian_particle(
        "particle_cartesian", (x, y, z), (x, y, z), particle_cartesian.__doc__
    )


def particle_cylindrical() -> ModelSpec:
    """An unconstrained particle in cylindrical coordinates r, phi, z (eqs. 7.5-7.9).

    x = r cos(phi), y = r sin(phi), z = z (z up, gravity along -z); phi from +x towards +y.
    Inputs Fx, Fy, Fz: Cartesian components of a further force, N; their generalised forces
    F_r (N), F_phi (N*m) and F_z (N) follow from eq. (6.15). Singular on the axis r = 0.
    """
    r, phi, z = me.dynamicsymbols("r phi z")
    position = (r * sp.cos(phi), r * sp.sin(phi), z)
    return cartesian_particle(
        "particle_cylindrical", (r, phi, z), position, particle_cylindrical.__doc__
    )


def particle_spherical() -> ModelSpec:
    """An unconstrained particle in spherical coordinates r, theta, phi (eqs. 7.10-7.13).

    x = r sin(theta) cos(phi), y = r sin(theta) sin(phi), z = r cos(theta): theta is the polar
    angle from +z (up; gravity along -z), phi the azimuth from +x towards +y. Inputs Fx, Fy,
    Fz: Cartesian components of a further force, N; F_r is a force, F_theta and F_phi are
    moments (N*m). Singular at the origin and on the polar axis (sin(theta) = 0).
    """
    r, theta, phi = me.dynamicsymbols("r theta phi")
    position = (
        r * sp.sin(theta) * sp.cos(phi),
        r * sp.sin(theta) * sp.sin(phi),
        r * sp.cos(theta),
    )
    return cartesian_particle(
        "particle_spherical", (r, theta, phi), position, particle_spherical.__doc__
    )


def frobenius_obstruction(a, b, c, variables) -> sp.Expr:
    """A . curl A for the 1-form a dx + b dy + c dz in `variables` (x, y, z).

    The Pfaffian constraint a dx + b dy + c dz = 0 is integrable (holonomic: it confines the
    particle to a family of surfaces) exactly where this vanishes identically (Frobenius).
    """
    x, y, z = variables
    curl = (
        sp.diff(c, y) - sp.diff(b, z),
        sp.diff(a, z) - sp.diff(c, x),
        sp.diff(b, x) - sp.diff(a, y),
    )
    return sp.simplify(a * curl[0] + b * curl[1] + c * curl[2])


def _position_expression(value, allowed: dict, what: str) -> sp.Expr:
    """`value` (sympy expression or text, read without running code) with the plain symbols
    of `allowed` replaced."""
    expr = parse_expression(value, what)
    unknown = {str(s) for s in expr.free_symbols} - set(allowed)
    if unknown:
        raise ValueError(
            f"{what} may use only {', '.join(sorted(allowed))}; got {', '.join(sorted(unknown))}."
        )
    return expr.xreplace({sp.Symbol(k): v for k, v in allowed.items()})


def particle_nonholonomic(a=None, b=None, c=None) -> ModelSpec:
    """A particle under one catastatic Pfaffian constraint a dx + b dy + c dz = 0 (eq. 7.16).

    Coordinates x, y, z (all three: a nonholonomic constraint removes a freedom of motion but
    no coordinate); one multiplier lambda1, entering as m x'' - F_x + lambda1 a = 0 etc.
    a, b, c: sympy expressions (or text, read without running code) in the plain symbols
    x, y, z and the length L.
    The default, a = -y / L, b = 0, c = 1 (dz = y dx / L), is genuinely nonholonomic: with
    A = (a, b, c), A . curl A = 1 / L is nowhere zero, so by Frobenius' theorem no family of
    surfaces f(x, y, z) = const carries the motion: dz = y dx / L, and since the loop integral
    of y dx is minus the enclosed area, taking the particle once counter-clockwise (seen
    from +z) around a closed loop in the (x, y) plane lowers it by the loop's area / L;
    clockwise raises it. Constant a, b, c would be integrable (the particle would stay on
    the plane a x + b y + c z = const).
    Gravity m g along -z; inputs Fx, Fy, Fz: a further force, N.
    """
    x, y, z = me.dynamicsymbols("x y z")
    L = sp.Symbol("L", positive=True)
    allowed = {"x": x, "y": y, "z": z, "L": L}
    defaults = {"a": -sp.Symbol("y") / L, "b": 0, "c": 1}
    given = {"a": a, "b": b, "c": c}
    coeff = [
        _position_expression(defaults[k] if v is None else v, allowed, f"coefficient {k}")
        for k, v in given.items()
    ]
    if all(sp.simplify(e) == 0 for e in coeff):
        raise ValueError("particle_nonholonomic: a, b and c are all zero: no constraint.")
    rates = sp.Matrix([x, y, z]).diff(t)
    constraint = sum((e * qd for e, qd in zip(coeff, rates)), sp.S.Zero)
    return cartesian_particle(
        "particle_nonholonomic",
        (x, y, z),
        (x, y, z),
        particle_nonholonomic.__doc__,
        constraints=(constraint,),
        parameters={L: Param(1.0, "m", "length scale of the default constraint dz = y dx / L")},
    )


def parabolic_line_element():
    """ds^2 in parabolic cylindrical coordinates (problem 7/1), from x = l (xi^2 - eta^2),
    y = 2 l xi eta, z = zeta: returns (ds2, (dxi, deta, dzeta), (xi, eta, zeta, l))."""
    xi, eta, zeta, dxi, deta, dzeta = sp.symbols("xi eta zeta dxi deta dzeta", real=True)
    l = sp.Symbol("l", positive=True)
    r = sp.Matrix([l * (xi**2 - eta**2), 2 * l * xi * eta, zeta])
    dr = r.jacobian([xi, eta, zeta]) * sp.Matrix([dxi, deta, dzeta])
    return sp.factor(sp.expand((dr.T * dr)[0, 0])), (dxi, deta, dzeta), (xi, eta, zeta, l)


def particle_parabolic_cylindrical() -> ModelSpec:
    """Problem 7/1: a free particle under a constant force X0 i + Y0 j + Z0 k, in parabolic
    cylindrical coordinates xi, eta, zeta: x = l (xi^2 - eta^2), y = 2 l xi eta, z = zeta.

    They are called parabolic cylindrical because the surfaces xi = const and eta = const
    are cylinders (along z) on confocal parabolas: eliminating eta from x and y gives
    x = l xi^2 - y^2 / (4 l xi^2), a parabola with focus on the z axis, opening towards -x.
    Arc length: ds^2 = 4 l^2 (xi^2 + eta^2) (dxi^2 + deta^2) + dzeta^2 (`parabolic_line_element`;
    the output `speed` is ds/dt). Outputs Xi, H, Z: the generalised forces of the constant
    force (N*m, N*m, N). No gravity beyond the force itself; inputs Fx, Fy, Fz add to it.
    The coordinates are singular on the z axis (xi = eta = 0).
    The force is conservative (potential -(X0 x + Y0 y + Z0 z)) but enters as a generalised
    force, not through V, so `energy()` is the kinetic energy alone and grows by the force's
    work; the conserved quantity is T - (X0 x + Y0 y + Z0 z), with x, y, z the outputs
    position_x, position_y, position_z.
    """
    xi, eta, zeta = me.dynamicsymbols("xi eta zeta")
    l = sp.Symbol("l", positive=True)
    X0, Y0, Z0 = sp.symbols("X0 Y0 Z0", real=True)
    q = (xi, eta, zeta)
    r = sp.Matrix([l * (xi**2 - eta**2), 2 * l * xi * eta, zeta])
    Q = generalized_forces(q, [(r.diff(t), sp.Matrix([X0, Y0, Z0]))])
    return cartesian_particle(
        "particle_parabolic_cylindrical",
        q,
        r,
        particle_parabolic_cylindrical.__doc__,
        gravity=False,
        forces=Q,
        parameters={
            l: Param(0.5, "m", "length scale of the coordinates"),
            X0: Param(1.0, "N", "x component of the constant force", False),
            Y0: Param(-0.5, "N", "y component of the constant force", False),
            Z0: Param(0.2, "N", "z component of the constant force", False),
        },
        outputs={
            "Xi": Q[xi],
            "H": Q[eta],
            "Z": Q[zeta],
            "speed": sp.sqrt(sp.simplify((r.diff(t).T * r.diff(t))[0, 0])),
        },
    )
