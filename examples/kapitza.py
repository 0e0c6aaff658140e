"""Kapitza's pendulum: a pendulum whose pivot is shaken up and down at high frequency, so
that the inverted position becomes stable; a motor at the pivot helps hold it upright.
`examples.kapitza:Examples/Kapitza-v0`.

The dynamics depend on time explicitly (the pivot's prescribed motion), so agents designed
on the dynamics at one time (LQR, the planner) refuse it; RL trains on it as on any env.
Inverted is stable without torque when A^2 w^2 > 2 g l (here 25 against 9.8 m^2/s^2).
"""

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me

import envs
from dynamics.spec import ModelSpec, Param, t


def kapitza() -> ModelSpec:
    """theta: angle from upright (rad, counter-clockwise +); a point mass m at distance l
    from a pivot at height A cos(w t). Input tau: torque at the pivot (N*m)."""
    th = me.dynamicsymbols("theta")
    m, l, g, A, w = sp.symbols("m l g A w", positive=True)
    tau = sp.Symbol("tau")
    x, y = -l * sp.sin(th), A * sp.cos(w * t) + l * sp.cos(th)
    T = m * (x.diff(t) ** 2 + y.diff(t) ** 2) / 2
    params = {
        m: Param(0.2, "kg"),
        l: Param(0.5, "m"),
        g: Param(9.81, "m/s^2"),
        A: Param(0.05, "m", "amplitude of the pivot's motion"),
        w: Param(100.0, "rad/s", "angular frequency of the pivot's motion"),
    }
    return ModelSpec("kapitza", (th,), T, m * g * y, params, (tau,), {th: tau})


def upright(x, a, goal, p):
    return np.cos(x.theta)


def effort(x, a, goal, p):
    return -0.01 * a.tau**2


def success(x, a, goal, p):
    return (np.abs(envs.wrap(x.theta)) < 0.1) & (np.abs(x.theta_dot) < 1.0)


def failure(x, a, goal, p):
    return np.abs(envs.wrap(x.theta)) > 1.0


TASK = envs.Task(
    name="Kapitza",
    model=kapitza,
    actuated=("tau",),
    max_input=(0.5,),
    observation=(envs.Angle("theta"), envs.Value("theta_dot", unit="rad/s")),
    terms=(
        envs.Term("upright", -1, 1, "cos theta", upright),
        envs.Term("effort", -0.01, 0, "-0.01 action^2", effort),
    ),
    success=success,
    failure=failure,
    start={"theta": (-0.3, 0.3), "theta_dot": (-0.5, 0.5)},
    limits={"theta_dot": 60.0},
    operating_point={},
    control_period=0.02,
    substeps=20,
    max_episode_steps=250,
)
envs.register("Examples/Kapitza-v0", TASK)
