"""The Whipple bicycle: two knife-edge wheels rolling on level ground, a rear frame with a
rigid rider and a steerable front assembly (Meijaard, Papadopoulos, Ruina and Schwab,
Proc. R. Soc. A 463 (2007) 1955-1982; their Table 1 gives the defaults)."""

from __future__ import annotations

import math

import sympy as sp
import sympy.physics.mechanics as me

from ..spec import ModelSpec, Param, generalized_forces, t


def whipple_bicycle() -> ModelSpec:
    """The benchmark bicycle of Meijaard et al. (2007): rear wheel R, rear frame B (with the
    rider), front frame H (fork and handlebar), front wheel F, four rigid bodies joined by
    three revolute hinges; the wheels are knife-edge discs rolling without slip on the level
    ground. No friction, no rider motion relative to B.

    Axes and angles (the paper's): N.x forward, N.y right, N.z down; the rear contact P is
    at (x, y) on the ground. psi: yaw (heading of B about N.z; positive turns right).
    phi: lean of B about its heading axis (positive leans right). theta: pitch of B about its
    axle (positive lifts the front; 0 in the reference configuration). delta: steer of H
    relative to B about the steering axis (positive turns the front wheel right). theta_R,
    theta_F: rotation of each wheel relative to B (rear) and H (front) about its axle
    (positive rolls backwards: forward motion at speed v has theta_R' = -v / r_R).
    Reference configuration (all angles 0): upright, straight ahead, rear contact at the
    origin, rear wheel centre (0, 0, -r_R), front wheel centre (w, 0, -r_F), the steering
    axis tilted back by lam from the vertical, meeting the ground the trail c ahead of the
    front contact (w, 0, 0). Mass centres and inertias are given in that configuration, in
    N's axes (inertia components I_xz as the tensor's own, like the paper's Table 1).

    Constraints, as the book writes them (section 7.5 for the disk): the rear contact is
    P itself, so the rear wheel's height is embedded; rolling without slip of each wheel's
    material contact point in the horizontal gives four nonholonomic (Pfaffian)
    constraints. The front wheel must touch the ground: the height of its lowest point
    above P, f(phi, theta, delta) = 0, is a holonomic constraint that fixes the pitch. It
    has no closed-form solution for theta in general, so instead of eliminating theta it
    enters in Pfaffian form, f' = 0 (the fifth constraint, which is also the vertical
    rolling condition of the front wheel), and the integrator's projection after each step
    keeps the rates on it. f itself is reported as the output `front_contact_height` (m):
    start from f = 0 and it stays at the integrator's truncation error (1.2e-9 m after 10 s
    of riding at 5 m/s, RK4 at dt = 0.01 s). Outputs also `speed`, the forward speed of P
    (m/s).

    Inputs (generalised forces by virtual work): T_phi, a lean torque on B about the
    heading axis from the ground (N*m; its work is T_phi dphi); T_delta, the steer torque
    of B on H about the steering axis (N*m); T_R, a drive torque of B on the rear wheel
    about its axle (N*m; positive rolls backwards). The paper's f = (T_phi, T_delta).
    Point for external forces (`ModelSpec.points`): rear_frame, B's mass centre
    (components along B's axes).
    """
    x, y, psi, phi, theta, delta, th_R, th_F = me.dynamicsymbols(
        "x y psi phi theta delta theta_R theta_F"
    )
    coords = (x, y, psi, phi, theta, delta, th_R, th_F)
    w, c, lam, g = sp.symbols("w c lam g", positive=True)
    r_R, m_R, I_Rxx, I_Ryy = sp.symbols("r_R m_R I_Rxx I_Ryy", positive=True)
    r_F, m_F, I_Fxx, I_Fyy = sp.symbols("r_F m_F I_Fxx I_Fyy", positive=True)
    x_B, m_B, I_Bxx, I_Byy, I_Bzz = sp.symbols("x_B m_B I_Bxx I_Byy I_Bzz", positive=True)
    x_H, m_H, I_Hxx, I_Hyy, I_Hzz = sp.symbols("x_H m_H I_Hxx I_Hyy I_Hzz", positive=True)
    z_B, I_Bxz, z_H, I_Hxz = sp.symbols("z_B I_Bxz z_H I_Hxz", real=True)
    T_phi, T_delta, T_R = sp.symbols("T_phi T_delta T_R")
    d = {q: q.diff(t) for q in coords}
    S, C = sp.sin, sp.cos

    # Frames: A (heading, psi about N.z), L (lean, phi about A.x; L.y is the rear axle),
    # B (rear frame, theta about L.y), E (B turned by lam about B.y: E.z is the steering
    # axis, pointing down), H (front frame, delta about E.z; H.y is the front axle), and
    # Hr (H turned back by lam about H.y: its axes are N's in the reference configuration).
    # Vectors are written by their components in B (rear parts) or H (front parts), so that
    # T, V and the constraints stay short.
    def b_to_h(v):
        """H components of a vector given by its B components."""
        ex, ey, ez = C(lam) * v[0] - S(lam) * v[2], v[1], S(lam) * v[0] + C(lam) * v[2]
        return sp.Matrix([C(delta) * ex + S(delta) * ey, -S(delta) * ex + C(delta) * ey, ez])

    def hr_to_h(a, b, z):
        """H components of the vector a Hr.x + b Hr.y + z Hr.z."""
        return sp.Matrix([C(lam) * a - S(lam) * z, b, S(lam) * a + C(lam) * z])

    def cross(a, b):
        return a.cross(b)

    # angular velocities: omega_B = psi' N.z + phi' A.x + theta' L.y (eq. 7.31's kind)
    omega_L = sp.Matrix(
        [
            d[phi] * C(theta) - d[psi] * C(phi) * S(theta),
            d[psi] * S(phi),
            d[phi] * S(theta) + d[psi] * C(phi) * C(theta),
        ]
    )
    omega_B = omega_L + sp.Matrix([0, d[theta], 0])
    omega_H = b_to_h(omega_B) + sp.Matrix([0, 0, d[delta]])
    down_B = sp.Matrix([-C(phi) * S(theta), S(phi), C(phi) * C(theta)])  # N.z
    down_H = b_to_h(down_B)
    ahead_B = sp.Matrix([C(theta), 0, S(theta)])  # A.x, the heading
    side_B = sp.Matrix([S(phi) * S(theta), C(phi), -S(phi) * C(theta)])  # A.y

    # the rear contact P moves on the ground: forward speed u, sideways speed s
    u = d[x] * C(psi) + d[y] * S(psi)
    s = -d[x] * S(psi) + d[y] * C(psi)
    v_P = u * ahead_B + s * side_B
    rho_R = sp.Matrix([r_R * S(theta), 0, -r_R * C(theta)])  # P to the rear centre: -r_R L.z
    v_R = v_P + cross(omega_L, rho_R)  # the rear centre (on B's axle)
    rho_B = sp.Matrix([x_B, 0, z_B + r_R])  # rear centre to B's mass centre
    rho_S = sp.Matrix([w + c, 0, r_R])  # rear centre to the steering axis at ground level
    v_B = v_R + cross(omega_B, rho_B)
    v_S = b_to_h(v_R + cross(omega_B, rho_S))  # from here on, H components
    rho_H = hr_to_h(x_H - w - c, 0, z_H)  # steering-axis foot to H's mass centre
    rho_F = hr_to_h(-c, 0, -r_F)  # steering-axis foot to the front centre
    v_H = v_S + cross(omega_H, rho_H)
    v_F = v_S + cross(omega_H, rho_F)

    spin_R = omega_B[1] + d[th_R]  # the wheels' angular velocities about their axles
    spin_F = omega_H[1] + d[th_F]
    I_B = sp.Matrix([[I_Bxx, 0, I_Bxz], [0, I_Byy, 0], [I_Bxz, 0, I_Bzz]])
    I_H = sp.Matrix([[I_Hxx, 0, I_Hxz], [0, I_Hyy, 0], [I_Hxz, 0, I_Hzz]])
    omega_Hr = sp.Matrix(
        [
            C(lam) * omega_H[0] + S(lam) * omega_H[2],
            omega_H[1],
            -S(lam) * omega_H[0] + C(lam) * omega_H[2],
        ]
    )

    def sq(v):
        return sum((e**2 for e in v), sp.S.Zero)

    T = (
        m_R * sq(v_R)
        + m_B * sq(v_B)
        + m_H * sq(v_H)
        + m_F * sq(v_F)
        + I_Rxx * (omega_B[0] ** 2 + omega_B[2] ** 2)
        + I_Ryy * spin_R**2
        + (omega_B.T * I_B * omega_B)[0, 0]
        + (omega_Hr.T * I_H * omega_Hr)[0, 0]
        + I_Fxx * (omega_H[0] ** 2 + omega_H[2] ** 2)
        + I_Fyy * spin_F**2
    ) / 2

    # depths below the ground (N.z is down): V = -g sum m z
    z_R = -r_R * C(phi)
    z_S = z_R + rho_S.dot(down_B)
    z_F = z_S + rho_F.dot(down_H)
    V = -g * (
        m_R * z_R + m_B * (z_R + rho_B.dot(down_B)) + m_H * (z_S + rho_H.dot(down_H)) + m_F * z_F
    )

    # The front wheel's lowest point lies r_F from its centre along d = (N.z - e H.y) / s,
    # the unit vector of the wheel's plane closest to N.z, with e = H.y . N.z and
    # s = sqrt(1 - e^2); in H components d = (down_x, 0, down_z) / s.
    tilt = sp.sqrt(down_H[0] ** 2 + down_H[2] ** 2)  # s
    height = z_F + r_F * tilt  # depth of the front contact below P: the holonomic f = 0

    # Rolling: the material contact points have no horizontal velocity. Rear: along the
    # heading and sideways. Front: along the horizontals t = H.y x N.z (the wheel's tangent)
    # and l = H.y - e N.z, both of length s (nonzero unless the wheel lies flat); there
    # v_contact = v_F + omega_F x r_F d, and d x t = s H.y, d x l = -s t give
    # v_contact . t = v_F . t + r_F s omega_F . H.y and v_contact . l = v_F . l -
    # r_F s omega_H . t. The vertical velocities vanish: the rear's identically (P is on
    # the ground), the front's is f', the holonomic constraint in Pfaffian form.
    slip_R = v_R + cross(omega_B + sp.Matrix([0, d[th_R], 0]), -rho_R)
    axle = sp.Matrix([0, 1, 0])
    tangent_F = cross(axle, down_H)
    lateral_F = axle - down_H[1] * down_H
    vertical_R = sp.simplify(slip_R.dot(down_B))
    if vertical_R != 0:  # the embedded holonomic constraint: P stays on the ground
        raise RuntimeError(f"whipple_bicycle: rear vertical slip {vertical_R} should vanish")
    constraints = (
        slip_R.dot(ahead_B),
        slip_R.dot(side_B),
        v_F.dot(tangent_F) + r_F * tilt * spin_F,
        v_F.dot(lateral_F) - r_F * tilt * omega_H.dot(tangent_F),
        height.diff(t),
    )

    # rider torques by virtual work: T_phi on B about A.x from the ground; T_delta of B on H
    # about the steering axis; T_R of B on the rear wheel about its axle
    Q = generalized_forces(
        coords,
        [
            (omega_B, T_phi * ahead_B),
            (omega_H - b_to_h(omega_B), T_delta * sp.Matrix([0, 0, 1])),
            (sp.Matrix([d[th_R]]), sp.Matrix([T_R])),
        ],
    )
    Q = {q: f for q, f in Q.items() if f != 0}
    return ModelSpec(
        name="whipple_bicycle",
        coordinates=coords,
        inputs=(T_phi, T_delta, T_R),
        kinetic=T,
        potential=V,
        forces=Q,
        constraints=constraints,
        outputs={"front_contact_height": height, "speed": u},
        parameters={
            w: Param(1.02, "m", "wheelbase (rear to front contact, reference configuration)"),
            c: Param(0.08, "m", "trail (front contact to the steering axis' ground point)"),
            lam: Param(math.pi / 10, "rad", "steering axis tilt from the vertical"),
            g: Param(9.81, "m/s^2", "gravitational acceleration"),
            r_R: Param(0.3, "m", "rear wheel radius"),
            m_R: Param(2.0, "kg", "rear wheel mass"),
            I_Rxx: Param(0.0603, "kg*m^2", "rear wheel moment of inertia about a diameter"),
            I_Ryy: Param(0.12, "kg*m^2", "rear wheel moment of inertia about its axle"),
            x_B: Param(0.3, "m", "rear frame mass centre, ahead of the rear contact"),
            z_B: Param(-0.9, "m", "rear frame mass centre's z (N.z down: -height)", False),
            m_B: Param(85.0, "kg", "rear frame mass (rider included)"),
            I_Bxx: Param(9.2, "kg*m^2", "rear frame inertia xx about its mass centre"),
            I_Byy: Param(11.0, "kg*m^2", "rear frame inertia yy about its mass centre"),
            I_Bzz: Param(2.8, "kg*m^2", "rear frame inertia zz about its mass centre"),
            I_Bxz: Param(2.4, "kg*m^2", "rear frame inertia xz about its mass centre", False),
            x_H: Param(0.9, "m", "front frame mass centre, ahead of the rear contact"),
            z_H: Param(-0.7, "m", "front frame mass centre's z (N.z down: -height)", False),
            m_H: Param(4.0, "kg", "front frame mass"),
            I_Hxx: Param(0.05892, "kg*m^2", "front frame inertia xx about its mass centre"),
            I_Hyy: Param(0.06, "kg*m^2", "front frame inertia yy about its mass centre"),
            I_Hzz: Param(0.00708, "kg*m^2", "front frame inertia zz about its mass centre"),
            I_Hxz: Param(-0.00756, "kg*m^2", "front frame inertia xz about its mass centre", False),
            r_F: Param(0.35, "m", "front wheel radius"),
            m_F: Param(3.0, "kg", "front wheel mass"),
            I_Fxx: Param(0.1405, "kg*m^2", "front wheel moment of inertia about a diameter"),
            I_Fyy: Param(0.28, "kg*m^2", "front wheel moment of inertia about its axle"),
        },
        description=whipple_bicycle.__doc__,
        # B's mass centre (rider included), components along B's axes
        points={"rear_frame": v_B},
        # the wheels are bodies of revolution (a diameter, the axle, a diameter); the frames'
        # tensors about their mass centres: each set of values must be some body's inertia
        bodies={
            "rear wheel": (I_Rxx, I_Ryy, I_Rxx),
            "rear frame": I_B,
            "front frame": I_H,
            "front wheel": (I_Fxx, I_Fyy, I_Fxx),
        },
    )
