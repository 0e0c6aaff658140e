"""The two-link robot arm of section 7.4."""

from __future__ import annotations

import sympy as sp
import sympy.physics.mechanics as me

from ..spec import ModelSpec, Param, generalized_forces

N = me.ReferenceFrame("N")  # N.x down (theta = 0 hangs), N.y horizontal, N.z out of the plane


def two_link_arm() -> ModelSpec:
    """Planar two-link arm under gravity (Fig. 7-4).

    theta1, theta2: absolute angles of links AC and CD from the downward vertical,
    counter-clockwise positive (theta = 0 hangs, theta = pi is inverted).
    Inputs: M1, the torque of the motor at the shoulder A (ground on link 1), and M2, the
    torque of the motor at the elbow C (link 1 on link 2), N*m. The elbow motor's reaction
    acts on link 1, so by virtual work, M1 d(theta1) + M2 (d(theta2) - d(theta1)),
    Q1 = M1 - M2 and Q2 = M2 (the book's Q1 = M1 holds only if M1 is the net torque on
    link 1; docs/errata.md).
    Points for external forces (`ModelSpec.points`, components along N.x down and N.y):
    link2, the mass centre D of link 2, and elbow, C.
    Parameters follow the book: l is AC, l1 the distance from A to the mass centre B of
    link 1, l2 from C to the mass centre D of link 2; Ibar1, Ibar2 central moments of
    inertia. Defaults: two uniform 1 kg, 1 m rods.
    """
    th1, th2 = me.dynamicsymbols("theta1 theta2")
    m1, m2, l, l1, l2, I1b, I2b, g = sp.symbols("m1 m2 l l1 l2 Ibar1 Ibar2 g", positive=True)
    M1, M2 = sp.symbols("M1 M2")

    link1 = N.orientnew("L1", "Axis", (th1, N.z))
    link2 = N.orientnew("L2", "Axis", (th2, N.z))
    A = me.Point("A")
    A.set_vel(N, 0)
    B = A.locatenew("B", l1 * link1.x)  # mass centre of link 1
    C = A.locatenew("C", l * link1.x)  # elbow
    D = C.locatenew("D", l2 * link2.x)  # mass centre of link 2
    vB, vD = B.pos_from(A).dt(N), D.pos_from(A).dt(N)
    w1, w2 = link1.ang_vel_in(N), link2.ang_vel_in(N)

    T = (m1 * vB.dot(vB) + I1b * w1.dot(w1) + m2 * vD.dot(vD) + I2b * w2.dot(w2)) / 2
    V = -(m1 * g * B.pos_from(A).dot(N.x) + m2 * g * D.pos_from(A).dot(N.x))
    Q = generalized_forces(
        (th1, th2),
        [(w1, M1 * N.z), (w1, -M2 * N.z), (w2, M2 * N.z)],  # motor 2 acts on both links
        frame=N,
    )
    return ModelSpec(
        name="two_link_arm",
        coordinates=(th1, th2),
        inputs=(M1, M2),
        kinetic=sp.simplify(T),
        potential=sp.simplify(V),
        forces=Q,
        parameters={
            m1: Param(1.0, "kg", "mass of link 1"),
            m2: Param(1.0, "kg", "mass of link 2"),
            l: Param(1.0, "m", "length of link 1 (shoulder A to elbow C)"),
            l1: Param(0.5, "m", "shoulder A to the mass centre B of link 1"),
            l2: Param(0.5, "m", "elbow C to the mass centre D of link 2"),
            I1b: Param(1.0 / 12.0, "kg*m^2", "central moment of inertia of link 1"),
            I2b: Param(1.0 / 12.0, "kg*m^2", "central moment of inertia of link 2"),
            g: Param(9.81, "m/s^2", "gravitational acceleration"),
        },
        description=two_link_arm.__doc__,
        points={
            "link2": sp.Matrix([vD.dot(N.x), vD.dot(N.y)]),
            "elbow": sp.Matrix([C.pos_from(A).dt(N).dot(e) for e in (N.x, N.y)]),
        },
    )
