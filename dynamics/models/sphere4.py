"""A particle on the surface of a sphere in four-dimensional space (problem 7/2)."""

from __future__ import annotations

from collections.abc import Mapping

import sympy as sp
import sympy.physics.mechanics as me

from ..parse import parse_expression
from ..spec import ModelSpec, Param, t

_DEFAULT_POTENTIAL = "k*R**2*cos(theta)**2/2"


def hypersphere_position(theta, varphi, psi, R) -> sp.Matrix:
    """(w, x, y, z) of the point (theta, varphi, psi) on the 4-sphere of radius R."""
    return sp.Matrix(
        [
            R * sp.cos(theta) * sp.cos(varphi),
            R * sp.cos(theta) * sp.sin(varphi),
            R * sp.sin(theta) * sp.cos(psi),
            R * sp.sin(theta) * sp.sin(psi),
        ]
    )


def particle_on_4_sphere(potential=None, potential_parameters: Mapping | None = None) -> ModelSpec:
    """Problem 7/2: a particle of unit mass on the 4-sphere w^2 + x^2 + y^2 + z^2 = R^2.

    Coordinates theta, varphi, psi: w = R cos(theta) cos(varphi), x = R cos(theta)
    sin(varphi), y = R sin(theta) cos(psi), z = R sin(theta) sin(psi). They satisfy the
    sphere identically and their Jacobian has rank 3 wherever sin(2 theta) != 0, so they are
    generalised coordinates of the 3-dimensional surface (varphi is undefined where
    cos(theta) = 0, psi where sin(theta) = 0, as longitude is at the poles).
    T = R^2 (theta'^2 + cos^2(theta) varphi'^2 + sin^2(theta) psi'^2) / 2 (mass m, 1 in the
    book). Since w^2 + x^2 = R^2 cos^2(theta), a potential constant on the cylinders
    w^2 + x^2 = const is a function V(theta) alone, and varphi, psi are cyclic: their
    momenta p_varphi = m R^2 cos^2(theta) varphi' and p_psi = m R^2 sin^2(theta) psi' are
    conserved (outputs p_varphi, p_psi; also the position w, x, y, z).
    potential: sympy expression (or text, read without running code) in theta, R and the
    names of `potential_parameters` ({name: default or Param}). Default V = k R^2 cos^2(theta) / 2,
    i.e. k (w^2 + x^2) / 2, a spring pulling the particle towards the plane w = x = 0.
    """
    theta, varphi, psi = me.dynamicsymbols("theta varphi psi")
    m, R = sp.symbols("m R", positive=True)
    if potential is None:
        if potential_parameters is not None:
            raise ValueError("potential_parameters are for a user potential; give it too.")
        potential = _DEFAULT_POTENTIAL
        potential_parameters = {"k": Param(2.0, "N/m", "stiffness of the default potential")}
    params = {
        name: value if isinstance(value, Param) else Param(float(value), "", "", False)
        for name, value in (potential_parameters or {}).items()
    }
    clash = {"theta", "R", "m"} & set(params)
    if clash:
        raise ValueError(f"particle_on_4_sphere: {sorted(clash)} are not parameter names.")
    V = parse_expression(potential, "the potential of particle_on_4_sphere")
    unknown = {str(s) for s in V.free_symbols} - {"theta", "R"} - set(params)
    if unknown:
        raise ValueError(
            f"particle_on_4_sphere: the potential may depend on theta (and R) only, plus "
            f"parameters given in potential_parameters; got {', '.join(sorted(unknown))}."
        )
    symbols = {name: sp.Symbol(name, real=True) for name in params}
    V = V.xreplace(
        {sp.Symbol(n): s for n, s in symbols.items()} | {sp.Symbol("theta"): theta}
    ).xreplace({sp.Symbol("R"): R})

    r = hypersphere_position(theta, varphi, psi, R)
    v = r.diff(t)
    T = sp.simplify(m * (v.T * v)[0, 0] / 2)
    outputs = dict(zip(("w", "x", "y", "z"), r))
    outputs["p_varphi"] = sp.diff(T, varphi.diff(t))
    outputs["p_psi"] = sp.diff(T, psi.diff(t))
    return ModelSpec(
        name="particle_on_4_sphere",
        coordinates=(theta, varphi, psi),
        kinetic=T,
        potential=V,
        outputs=outputs,
        parameters={
            m: Param(1.0, "kg", "mass of the particle (unit mass in the book)"),
            R: Param(1.0, "m", "radius of the 4-sphere"),
            **{symbols[n]: p for n, p in params.items()},
        },
        description=particle_on_4_sphere.__doc__,
    )
