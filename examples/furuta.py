"""Rotary (Furuta) pendulum: a motor turns a horizontal arm whose tip carries a pendulum
swinging across the arm; balance it upright. `examples.furuta:Examples/Furuta-v0`."""

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me

import envs
from dynamics.spec import ModelSpec, Param


def furuta() -> ModelSpec:
    """alpha: arm angle about the vertical (counter-clockwise from above); theta: pendulum
    angle from upright about the arm (rad); a uniform rod of length 2 l. Input tau (N*m)."""
    alpha, theta = me.dynamicsymbols("alpha theta")
    J, m, r, l, g, tau = *sp.symbols("J m r l g", positive=True), sp.Symbol("tau")
    N = me.ReferenceFrame("N")  # N.z up
    A = N.orientnew("A", "Axis", (alpha, N.z))  # the arm lies along A.x
    P = A.orientnew("P", "Axis", (theta, A.x))  # the pendulum lies along P.z
    c, w = r * A.x + l * P.z, P.ang_vel_in(N)  # the pendulum's mass centre, its rotation
    T = J * alpha.diff() ** 2 / 2 + m * c.dt(N).dot(c.dt(N)) / 2
    T += w.dot(me.inertia(P, m * l**2 / 3, m * l**2 / 3, 0).dot(w)) / 2
    params = {
        J: Param(0.01, "kg*m^2"),
        m: Param(0.1, "kg"),
        r: Param(0.2, "m"),
        l: Param(0.15, "m"),
        g: Param(9.81, "m/s^2"),
    }
    V = m * g * c.dot(N.z)
    return ModelSpec("furuta", (alpha, theta), sp.simplify(T), V, params, (tau,), {alpha: tau})


def upright(x, a, goal, p):
    return np.cos(x.theta)


def arm(x, a, goal, p):
    return -0.1 * envs.wrap(x.alpha) ** 2


def effort(x, a, goal, p):
    return -0.01 * a.tau**2


def success(x, a, goal, p):
    still = (np.abs(x.theta_dot) < 0.3) & (np.abs(x.alpha_dot) < 0.3)
    return (np.abs(envs.wrap(x.theta)) < 0.05) & still


def failure(x, a, goal, p):
    return np.abs(envs.wrap(x.theta)) > 0.6


TASK = envs.Task(
    name="Furuta",
    model=furuta,
    actuated=("tau",),
    max_input=(0.5,),
    observation=(
        envs.Angle("alpha"),
        envs.Angle("theta"),
        envs.Value("alpha_dot", unit="rad/s"),
        envs.Value("theta_dot", unit="rad/s"),
    ),
    terms=(
        envs.Term("upright", -1, 1, "cos theta", upright),
        envs.Term("arm", -0.1 * np.pi**2, 0, "-0.1 alpha^2 (wrapped)", arm),
        envs.Term("effort", -0.01, 0, "-0.01 action^2", effort),
    ),
    success=success,
    failure=failure,
    start={"alpha": (-0.3, 0.3), "theta": (-0.1, 0.1), "theta_dot": (-0.1, 0.1)},
    limits={"alpha_dot": 40.0, "theta_dot": 40.0},
    operating_point={},
    control_period=0.02,
    substeps=4,
    max_episode_steps=500,
    lqr=envs.LQRHints(region={"alpha": 0.3, "theta": 0.1, "theta_dot": 0.1}),
)
envs.register("Examples/Furuta-v0", TASK)
