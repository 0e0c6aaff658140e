"""The bead on a rod turning in a vertical plane (problem 7/4), prescribed or driven."""

from __future__ import annotations

import sympy as sp
import sympy.physics.mechanics as me

from ..spec import ModelSpec, Param, generalized_forces, t


def _bead_energies(r, phi, m, g):
    """T and V of the bead at distance r along a rod at angle phi above the horizontal."""
    x, y = r * sp.cos(phi), r * sp.sin(phi)
    T = m * (x.diff(t) ** 2 + y.diff(t) ** 2) / 2
    return sp.simplify(T), m * g * y


def bead_on_rotating_rod() -> ModelSpec:
    """Problem 7/4: a heavy bead on a smooth rod spun at constant rate Omega.

    The rod turns in a vertical plane about a fixed point O on its centre line; phi, its
    angle above the horizontal, is prescribed: phi = Omega t (horizontal at t = 0), a
    rheonomic constraint. Coordinate r: the bead's signed distance from O along the rod.
    Output `reaction_phi`: the torque on the rod that keeps the rate constant, N*m (the
    rod's own inertia needs none at constant rate).
    """
    r, phi = me.dynamicsymbols("r phi")
    m, g, Omega = sp.symbols("m g Omega", positive=True)
    T, V = _bead_energies(r, phi, m, g)
    return ModelSpec(
        name="bead_on_rotating_rod",
        coordinates=(r,),
        kinetic=T,
        potential=V,
        prescribed={phi: Omega * t},
        parameters={
            m: Param(0.1, "kg", "mass of the bead"),
            g: Param(9.81, "m/s^2", "gravitational acceleration"),
            Omega: Param(2.0, "rad/s", "rate of the rod, counter-clockwise"),
        },
        description=bead_on_rotating_rod.__doc__,
    )


def bead_on_driven_rod() -> ModelSpec:
    """The rod of problem 7/4 free about its pivot O and driven by a motor torque.

    Coordinates: r, the bead's signed distance from O along the rod, and phi, the rod's
    angle above the horizontal (counter-clockwise +). The rod is balanced about O (its
    mass centre at O) with moment of inertia J about O. Input tau: motor torque on the rod
    (ground on rod, counter-clockwise +), N*m. The rod reaches rod_length/2 either side of
    O; leaving it is for the environment to judge. Point for external forces
    (`ModelSpec.points`): bead (components horizontal and up).
    """
    r, phi = me.dynamicsymbols("r phi")
    m, g, J, L = sp.symbols("m g J rod_length", positive=True)
    tau = sp.Symbol("tau")
    T, V = _bead_energies(r, phi, m, g)
    T = T + J * phi.diff(t) ** 2 / 2
    Q = generalized_forces((r, phi), [(sp.Matrix([phi.diff(t)]), sp.Matrix([tau]))])
    return ModelSpec(
        name="bead_on_driven_rod",
        coordinates=(r, phi),
        inputs=(tau,),
        kinetic=T,
        potential=V,
        forces=Q,
        parameters={
            m: Param(0.1, "kg", "mass of the bead"),
            J: Param(0.1, "kg*m^2", "moment of inertia of the rod about its pivot"),
            L: Param(2.0, "m", "length of the rod (pivot at its middle)"),
            g: Param(9.81, "m/s^2", "gravitational acceleration"),
        },
        description=bead_on_driven_rod.__doc__,
        points={"bead": sp.Matrix([r * sp.cos(phi), r * sp.sin(phi)]).diff(t)},
    )
