"""The thin disk rolling without slipping on a horizontal plane (section 7.5)."""

from __future__ import annotations

import sympy as sp
import sympy.physics.mechanics as me

from ..spec import ModelSpec, Param, generalized_forces

N = me.ReferenceFrame("N")  # N.x, N.z horizontal, N.y up (the book's i, k and j)


def rolling_disk() -> ModelSpec:
    """A thin uniform disk rolling on the plane y = 0 (Figs. 7-7, 7-8).

    Coordinates, in the order of eq. (7.35): x, z, the contact point on the floor; theta,
    the tilt of the disk's plane from the floor (pi/2 upright; theta < pi/2 leans the disk
    towards the horizontal j x i' = cos(phi) i - sin(phi) k, where its centre lies
    r cos(theta) from the contact point as in Fig. 7-8; that is -k' of the upright disk);
    phi, the heading: rotation of the rolling direction i' about the vertical j
    (i' = sin(phi) i + cos(phi) k); psi, the spin about the disk's axis k'. With these
    Euler angles omega = theta' i' + phi' j + psi' k' (eq. 7.31).
    The rolling constraints are derived here from zero velocity of the material contact
    point (they come out as eqs. 7.27-7.28: x' = -r psi' sin(phi), z' = -r psi' cos(phi)).
    Inputs: tau_drive, a torque on the disk about its axle k' (N*m), and tau_steer, a torque
    about the vertical j (N*m); their generalised forces follow from virtual work.
    Defaults: a uniform thin disk, I = m r^2 / 4 (diameter), J = m r^2 / 2 (axis).
    Point for external forces (`ModelSpec.points`, components along i, j, k): centre.
    """
    x, z, theta, phi, psi = me.dynamicsymbols("x z theta phi psi")
    m, r, I, J, g = sp.symbols("m r I J g", positive=True)
    tau_d, tau_s = sp.symbols("tau_drive tau_steer")

    heading = N.orientnew("H", "Axis", (phi, N.y))  # H.z = i' (rolling direction)
    lean = heading.orientnew("P", "Axis", (theta, heading.z))  # P.x = j', P.y = k', P.z = i'
    body = lean.orientnew("D", "Axis", (psi, lean.y))  # spin about the axle k'

    contact = me.Point("contact")  # the geometric contact point, moving on the floor
    contact.set_vel(N, x.diff() * N.x + z.diff() * N.z)
    centre = contact.locatenew("G", r * lean.x)  # j' runs from the contact to the centre
    v_centre = contact.vel(N) + (r * lean.x).dt(N)
    omega = body.ang_vel_in(N)
    # the material point of the disk at the contact: v = v_G + omega x (-r j')
    v_slip = v_centre + omega.cross(-r * lean.x)
    constraints = (sp.simplify(v_slip.dot(N.x)), sp.simplify(v_slip.dot(N.z)))
    vertical = sp.simplify(v_slip.dot(N.y))
    if vertical != 0:  # the embedded holonomic constraint y_contact = 0
        raise RuntimeError(f"rolling_disk: vertical slip {vertical} should vanish")

    T = (
        m * v_centre.dot(v_centre)
        + I * (omega.dot(lean.x) ** 2 + omega.dot(lean.z) ** 2)
        + J * omega.dot(lean.y) ** 2
    ) / 2
    V = m * g * centre.pos_from(contact).dot(N.y)
    Q = generalized_forces(
        (x, z, theta, phi, psi),
        [(omega, tau_d * lean.y), (omega, tau_s * N.y)],
        frame=N,
    )
    return ModelSpec(
        name="rolling_disk",
        coordinates=(x, z, theta, phi, psi),
        inputs=(tau_d, tau_s),
        kinetic=sp.simplify(T),
        potential=sp.simplify(V),
        forces=Q,
        constraints=constraints,
        parameters={
            m: Param(1.0, "kg", "mass of the disk"),
            r: Param(0.3, "m", "radius of the disk"),
            I: Param(0.0225, "kg*m^2", "moment of inertia about a diameter (m r^2 / 4)"),
            J: Param(0.045, "kg*m^2", "moment of inertia about the axle (m r^2 / 2)"),
            g: Param(9.81, "m/s^2", "gravitational acceleration"),
        },
        description=rolling_disk.__doc__,
        points={"centre": v_centre.to_matrix(N)},
        bodies={"disk": (I, I, J)},  # about two diameters and the axle (J <= 2 I)
    )
