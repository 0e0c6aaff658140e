"""A particle on a moving planar curve y = f(x, t) (section 7.3, eqs. 7.14-7.15)."""

from __future__ import annotations

from collections.abc import Mapping

import sympy as sp
import sympy.physics.mechanics as me

from ..parse import parse_expression
from ..spec import ModelSpec, Param, generalized_forces, t

_DEFAULT_CURVE = "k*x**2 + A*sin(Omega*t)"
_DEFAULT_PARAMETERS = {
    "k": Param(0.5, "1/m", "curvature coefficient of the parabola y = k x^2 + ..."),
    "A": Param(0.2, "m", "amplitude of the parabola's vertical oscillation", False),
    "Omega": Param(3.0, "rad/s", "angular frequency of the oscillation"),
}


def _curve(curve, curve_parameters: Mapping | None) -> tuple[sp.Expr, dict]:
    """The curve as an expression in x(t), t and parameter symbols, with those parameters."""
    if curve is None:
        if curve_parameters is not None:
            raise ValueError("curve_parameters are for a user curve; give `curve` too.")
        curve, params = _DEFAULT_CURVE, _DEFAULT_PARAMETERS
    else:
        params = {}
        for name, value in (curve_parameters or {}).items():
            params[name] = value if isinstance(value, Param) else Param(float(value), "", "", False)
    f = parse_expression(curve, "the curve of particle_on_curve")
    names = {str(s) for s in f.free_symbols}
    reserved = {"x", "t", "m", "g"} & set(params)
    if reserved:
        raise ValueError(f"particle_on_curve: {sorted(reserved)} are not curve parameter names.")
    unknown = names - {"x", "t"} - set(params)
    if unknown:
        raise ValueError(
            f"particle_on_curve: the curve uses {', '.join(sorted(unknown))}; give their "
            "values in curve_parameters={name: value}."
        )
    if "x" not in names:
        raise ValueError(f"particle_on_curve: the curve {f} does not depend on x.")
    symbols = {name: sp.Symbol(name, real=True) for name in params}
    x = me.dynamicsymbols("x")
    f = f.xreplace({sp.Symbol(n): s for n, s in symbols.items()} | {sp.Symbol("x"): x})
    return f, {symbols[n]: p for n, p in params.items()}


def particle_on_curve(curve=None, curve_parameters: Mapping | None = None) -> ModelSpec:
    """A particle in a vertical plane on the smooth curve y = f(x, t) (Fig. 7-3).

    x right, y up; gravity m g along -y. The holonomic constraint is embedded: x is the one
    coordinate and y = f(x, t) enters T = m (x'^2 + y'^2) / 2 through y' = f_x x' + f_t.
    A curve that moves (f depends on t) is rheonomic: the energy then changes by the work of
    the curve on the particle; a fixed curve (scleronomic) gives eq. (7.15).
    curve: sympy expression (or text, read by `dynamics.parse` without running code) in the
    plain symbols x and t and any parameters named in `curve_parameters` ({name: default
    value or Param}). Default: the parabola y = k x^2 + A sin(Omega t), which heaves up and
    down.
    Inputs Fx, Fy: Cartesian components of a further given force, N; with gravity they
    give, by virtual work, Q_x = Fx + (Fy - m g) f_x (the x component alone only when the
    force has no y component). Outputs: position_y = f(x, t) and normal_force, the
    curve's push on the particle along the upward normal (N).
    """
    f, curve_params = _curve(curve, curve_parameters)
    x = me.dynamicsymbols("x")
    m, g = sp.symbols("m g", positive=True)
    Fx, Fy = sp.symbols("Fx Fy")
    r = sp.Matrix([x, f])
    v = r.diff(t)
    T = m * (v.T * v)[0, 0] / 2
    Q = generalized_forces((x,), [(v, sp.Matrix([Fx, Fy]))])
    # normal force: m a = F + (0, -m g) + N n with n = (-f_x, 1) / sqrt(1 + f_x^2)
    fx = f.diff(x)
    a = v.diff(t)
    normal = ((m * a - sp.Matrix([Fx, Fy - m * g])).T * sp.Matrix([-fx, 1]))[0, 0]
    return ModelSpec(
        name="particle_on_curve",
        coordinates=(x,),
        inputs=(Fx, Fy),
        kinetic=T,
        potential=m * g * f,
        forces=Q,
        outputs={"position_y": f, "normal_force": normal / sp.sqrt(1 + fx**2)},
        parameters={
            m: Param(1.0, "kg", "mass of the particle"),
            g: Param(9.81, "m/s^2", "gravitational acceleration, along -y", False),
            **curve_params,
        },
        description=particle_on_curve.__doc__,
    )
