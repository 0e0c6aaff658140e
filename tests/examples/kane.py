"""The new examples' equations of motion derived a second way, independently of their
`ModelSpec`s: Kane's method (`sympy.physics.mechanics.KanesMethod`) from the bodies, their
mass centres and inertias, and the applied forces and torques, never from the examples'
kinetic energy, potential or generalised forces. Each builder returns a `Reference` whose
`accelerations(x, u)` is the second derivative of the coordinates, in the example's
coordinate order, at a state x = [q, qdot] and inputs u (numbers)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me


@dataclass
class Reference:
    """q'' = f(x, u) by Kane's method, with the parameters substituted."""

    accelerations_fn: object  # (q..., u..., inputs...) -> (M, F) with M [q'; u']' = F
    n: int
    energy_fn: object | None = None  # (q..., u...) -> T + V, where the builder gives it

    def accelerations(self, x, u):
        M, F = self.accelerations_fn(*x, *u)
        return np.linalg.solve(np.asarray(M, float), np.asarray(F, float).ravel())[self.n :]

    def energy(self, x):
        return float(self.energy_fn(*x))


def _reference(kane, q, u, inputs, bodies, loads, params, potential=None, N=None):
    kane.kanes_equations(bodies, loads)
    plain_q = sp.symbols(f"q0:{len(q)}")
    plain_u = sp.symbols(f"u0:{len(u)}")
    swap = dict(zip(q, plain_q)) | dict(zip(u, plain_u))
    values = {sp.Symbol(k) if isinstance(k, str) else k: v for k, v in params.items()}
    M = kane.mass_matrix_full.subs(values).xreplace(swap)
    F = kane.forcing_full.subs(values).xreplace(swap)
    args = (*plain_q, *plain_u, *inputs)
    fn = sp.lambdify(args, (M, F), "numpy")
    energy = None
    if potential is not None:
        T = sum(b.kinetic_energy(N) for b in bodies)
        # the kinetic energy reads q' where the bodies' velocities were given in q'
        T = T.subs({qi.diff(): ui for qi, ui in zip(q, u)})
        E = (T + potential).subs(values).xreplace(swap)
        energy = sp.lambdify((*plain_q, *plain_u), E, "numpy")
    return Reference(fn, len(q), energy)


def _planar(q, speeds, make, params, inputs):
    """A planar system with u = q': `make(N, O)` -> (bodies, loads, potential)."""
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    bodies, loads, V = make(N, O)
    kd = [qi.diff() - ui for qi, ui in zip(q, speeds)]
    kane = me.KanesMethod(N, q_ind=q, u_ind=speeds, kd_eqs=kd)
    return _reference(kane, q, speeds, inputs, bodies, loads, params, V, N)


def _body(name, frame, point, mass, inertia):
    return me.RigidBody(name, point, frame, mass, (inertia, point))


def reaction_wheel(params) -> Reference:
    """Rod R about the fixed pivot O (R.y along it); the wheel W at its tip, spun by phi
    relative to R; the motor's tau on W and -tau on R, the bearing's friction likewise."""
    th, ph = me.dynamicsymbols("theta phi")
    u1, u2 = me.dynamicsymbols("u1 u2")
    m_r, L, m_w, I_w, b, g, tau = sp.symbols("m_rod l_rod m_wheel I_wheel b_wheel g tau")

    def make(N, O):
        R = N.orientnew("R", "Axis", (th, N.z))
        W = R.orientnew("W", "Axis", (ph, R.z))
        R.set_ang_vel(N, u1 * N.z)
        W.set_ang_vel(R, u2 * R.z)
        c, w = O.locatenew("c", L / 2 * R.y), O.locatenew("w", L * R.y)
        c.v2pt_theory(O, N, R)
        w.v2pt_theory(O, N, R)
        rod = _body("rod", R, c, m_r, me.inertia(R, 0, 0, m_r * L**2 / 12))
        wheel = _body("wheel", W, w, m_w, me.inertia(W, 0, 0, I_w))
        drive = tau - b * u2
        loads = [
            (c, -m_r * g * N.y),
            (w, -m_w * g * N.y),
            (W, drive * N.z),
            (R, -drive * N.z),
        ]
        V = g * (m_r * c.pos_from(O).dot(N.y) + m_w * w.pos_from(O).dot(N.y))
        return [rod, wheel], loads, V

    return _planar([th, ph], [u1, u2], make, params, [tau])


def pendubot(params) -> Reference:
    """Link 1 about O (absolute theta1), link 2 about the elbow E (theta2 relative to
    link 1); tau and the shoulder's friction on link 1, the elbow's friction between."""
    th1, th2 = me.dynamicsymbols("theta1 theta2")
    u1, u2 = me.dynamicsymbols("u1 u2")
    m1, m2, l1, l2, b1, b2, g, tau = sp.symbols("m1 m2 l1 l2 b1 b2 g tau")

    def make(N, O):
        A = N.orientnew("A", "Axis", (th1, N.z))
        B = A.orientnew("B", "Axis", (th2, A.z))
        A.set_ang_vel(N, u1 * N.z)
        B.set_ang_vel(A, u2 * A.z)
        c1, E = O.locatenew("c1", l1 / 2 * A.y), O.locatenew("E", l1 * A.y)
        c2 = E.locatenew("c2", l2 / 2 * B.y)
        for point in (c1, E):
            point.v2pt_theory(O, N, A)
        c2.v2pt_theory(E, N, B)
        link1 = _body("link1", A, c1, m1, me.inertia(A, 0, 0, m1 * l1**2 / 12))
        link2 = _body("link2", B, c2, m2, me.inertia(B, 0, 0, m2 * l2**2 / 12))
        loads = [
            (c1, -m1 * g * N.y),
            (c2, -m2 * g * N.y),
            (A, (tau - b1 * u1 + b2 * u2) * N.z),
            (B, -b2 * u2 * N.z),
        ]
        V = g * (m1 * c1.pos_from(O).dot(N.y) + m2 * c2.pos_from(O).dot(N.y))
        return [link1, link2], loads, V

    return _planar([th1, th2], [u1, u2], make, params, [tau])


def gantry_crane(params) -> Reference:
    """Trolley P on the rail (N.x), the load a particle on a rope at angle phi from the
    downward vertical; F and the friction on the trolley, gravity on the load."""
    x, phi = me.dynamicsymbols("x phi")
    u1, u2 = me.dynamicsymbols("u1 u2")
    M, m, l, c, g, F = sp.symbols("m_trolley m_load l c g F")

    def make(N, O):
        R = N.orientnew("R", "Axis", (phi, N.z))  # the rope along -R.y
        R.set_ang_vel(N, u2 * N.z)
        P = O.locatenew("P", x * N.x)
        P.set_vel(N, u1 * N.x)
        load = P.locatenew("load", -l * R.y)
        load.v2pt_theory(P, N, R)
        bodies = [me.Particle("trolley", P, M), me.Particle("load", load, m)]
        loads = [(P, (F - c * u1) * N.x), (load, -m * g * N.y)]
        return bodies, loads, m * g * load.pos_from(O).dot(N.y)

    return _planar([x, phi], [u1, u2], make, params, [F])


def series_elastic(params) -> Reference:
    """Rotor and link on fixed axes; the spring's torque k (theta_m - theta) on the link and
    its reaction on the rotor; tau and the friction on the rotor; gravity on the link."""
    th_m, th = me.dynamicsymbols("theta_m theta")
    u1, u2 = me.dynamicsymbols("u1 u2")
    J_m, b_m, k, m, l, g, tau = sp.symbols("J_m b_m k m l g tau")

    def make(N, O):
        Rm = N.orientnew("Rm", "Axis", (th_m, N.z))
        Lk = N.orientnew("Lk", "Axis", (th, N.z))  # the link along -Lk.y
        Rm.set_ang_vel(N, u1 * N.z)
        Lk.set_ang_vel(N, u2 * N.z)
        c = O.locatenew("c", -l / 2 * Lk.y)
        c.v2pt_theory(O, N, Lk)
        rotor = _body("rotor", Rm, O, 1, me.inertia(Rm, 0, 0, J_m))
        link = _body("link", Lk, c, m, me.inertia(Lk, 0, 0, m * l**2 / 12))
        spring = k * (th_m - th)
        loads = [
            (Rm, (tau - b_m * u1 - spring) * N.z),
            (Lk, spring * N.z),
            (c, -m * g * N.y),
        ]
        V = m * g * c.pos_from(O).dot(N.y) + k * (th_m - th) ** 2 / 2
        return [rotor, link], loads, V

    return _planar([th_m, th], [u1, u2], make, params, [tau])


def planar_vtol(params) -> Reference:
    """A rigid body B in the plane; thrusts T1, T2 along B.y at -d and +d along B.x."""
    x, y, th = me.dynamicsymbols("x y theta")
    u1, u2, u3 = me.dynamicsymbols("u1 u2 u3")
    m, I, d, g, T1, T2 = sp.symbols("m I d g T1 T2")

    def make(N, O):
        B = N.orientnew("B", "Axis", (th, N.z))
        B.set_ang_vel(N, u3 * N.z)
        C = O.locatenew("C", x * N.x + y * N.y)
        C.set_vel(N, u1 * N.x + u2 * N.y)
        r1, r2 = C.locatenew("r1", -d * B.x), C.locatenew("r2", d * B.x)
        r1.v2pt_theory(C, N, B)
        r2.v2pt_theory(C, N, B)
        body = _body("body", B, C, m, me.inertia(B, 0, 0, I))
        loads = [(C, -m * g * N.y), (r1, T1 * B.y), (r2, T2 * B.y)]
        return [body], loads, m * g * y

    return _planar([x, y, th], [u1, u2, u3], make, params, [T1, T2])


def segway(params) -> Reference:
    """Body B pitching about the axle, wheels WL, WR spinning about it at +-d; each wheel's
    contact point at rest (Kane's dependent speeds x', y', psi'); the motors' torques on
    the wheels and their reactions on the body."""
    q = x, y, psi, th, ph_l, ph_r = me.dynamicsymbols("x y psi theta phi_l phi_r")
    u = ux, uy, upsi, uth, ul, ur = me.dynamicsymbols("ux uy upsi uth ul ur")
    M, l, Ip, Ir, Iy = sp.symbols("M l I_pitch I_roll I_yaw")
    m_w, r, J, K, d, g, tau_l, tau_r = sp.symbols("m_w r J_w K_w d g tau_l tau_r")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    H = N.orientnew("H", "Axis", (psi, N.z))
    H.set_ang_vel(N, upsi * N.z)
    B = H.orientnew("B", "Axis", (th, H.y))
    B.set_ang_vel(H, uth * H.y)
    A = O.locatenew("A", x * N.x + y * N.y)  # the axle's middle, at wheel-centre height
    A.set_vel(N, ux * N.x + uy * N.y)
    c = A.locatenew("c", l * B.z)
    c.v2pt_theory(A, N, B)
    bodies = [_body("body", B, c, M, me.inertia(B, Ir, Ip, Iy))]
    loads = [(c, -M * g * N.z), (B, -(tau_l + tau_r) * H.y)]
    constraints = [-ux * sp.sin(psi) + uy * sp.cos(psi)]
    for side, ph, w, tau in ((1, ph_l, ul, tau_l), (-1, ph_r, ur, tau_r)):
        W = H.orientnew(f"W{side}", "Axis", (ph, H.y))
        W.set_ang_vel(H, w * H.y)
        centre = A.locatenew(f"w{side}", side * d * H.y)
        centre.v2pt_theory(A, N, H)
        contact = centre.locatenew(f"p{side}", -r * N.z)
        contact.v2pt_theory(centre, N, W)
        constraints.append(contact.vel(N).dot(H.x))  # rolling: the contact point at rest
        bodies.append(_body(f"wheel{side}", W, centre, m_w, me.inertia(W, K, J, K)))
        loads.append((W, tau * H.y))
    kd = [qi.diff() - ui for qi, ui in zip(q, u)]
    kane = me.KanesMethod(
        N,
        q_ind=list(q),
        u_ind=[uth, ul, ur],
        kd_eqs=kd,
        u_dependent=[ux, uy, upsi],
        velocity_constraints=constraints,
    )
    ref = _reference(kane, list(q), [uth, ul, ur, ux, uy, upsi], [tau_l, tau_r], bodies,
                     loads, params)  # fmt: skip
    order = [3, 4, 5, 0, 1, 2]  # Kane's u order (uth, ul, ur, ux, uy, upsi) -> q order

    class SegwayReference(Reference):
        def accelerations(self, x, inputs):
            x = np.asarray(x, float)
            qd = x[6:]
            kane_u = np.array([qd[3], qd[4], qd[5], qd[0], qd[1], qd[2]])
            M, F = ref.accelerations_fn(*x[:6], *kane_u, *inputs)
            sol = np.linalg.solve(np.asarray(M, float), np.asarray(F, float).ravel())[6:]
            return sol[order]

    return SegwayReference(ref.accelerations_fn, 6)
