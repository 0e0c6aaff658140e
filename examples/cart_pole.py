"""Cart-pole: balance a uniform pole on a cart pushed by a horizontal force (Gymnasium's
CartPole-v1 system, with a continuous force). `examples.cart_pole:Examples/CartPole-v0`."""

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me

import envs
from dynamics.spec import ModelSpec, Param, t


def cart_pole() -> ModelSpec:
    """x: cart position (m, right +); theta: pole angle from upright (rad, tipping right +);
    l: half the pole's length. Input F: horizontal force on the cart (N)."""
    x, th = me.dynamicsymbols("x theta")
    M, m, l, g, F = *sp.symbols("m_cart m_pole l g", positive=True), sp.Symbol("F")
    px, py = x + l * sp.sin(th), l * sp.cos(th)  # the pole's mass centre
    T = (M * x.diff(t) ** 2 + m * (px.diff(t) ** 2 + py.diff(t) ** 2)) / 2
    T += m * l**2 / 6 * th.diff(t) ** 2  # rotation about the centre: I = m (2 l)^2 / 12
    params = {M: Param(1.0, "kg"), m: Param(0.1, "kg"), l: Param(0.5, "m"), g: Param(9.8, "m/s^2")}
    return ModelSpec("cart_pole", (x, th), T, m * g * py, params, inputs=(F,), forces={x: F})


def upright(x, a, goal, p):
    return np.cos(x.theta)


def centre(x, a, goal, p):
    return -0.1 * (x.x / 2.4) ** 2


def effort(x, a, goal, p):
    return -0.001 * a.F**2


def success(x, a, goal, p):
    return (np.abs(x.theta) < 0.05) & (np.abs(x.x) < 0.1) & (np.abs(x.theta_dot) < 0.2)


def failure(x, a, goal, p):
    return (np.abs(x.x) > 2.4) | (np.abs(envs.wrap(x.theta)) > 0.5)


TASK = envs.Task(
    name="CartPole",
    model=cart_pole,
    actuated=("F",),
    max_input=(10.0,),
    observation=(
        envs.Value("x", unit="m"),
        envs.Angle("theta"),
        envs.Value("x_dot", unit="m/s"),
        envs.Value("theta_dot", unit="rad/s"),
    ),
    terms=(
        envs.Term("upright", -1, 1, "cos theta", upright),
        envs.Term("centre", -0.4, 0, "-0.1 (x / 2.4)^2", centre),
        envs.Term("effort", -0.001, 0, "-0.001 action^2", effort),
    ),
    success=success,
    failure=failure,
    start={"x": (-0.5, 0.5), "theta": (-0.1, 0.1), "x_dot": (-0.1, 0.1), "theta_dot": (-0.1, 0.1)},
    limits={"x": 4.8, "x_dot": 10.0, "theta_dot": 20.0},
    operating_point={},
    control_period=0.02,
    substeps=4,
    max_episode_steps=500,
    lqr=envs.LQRHints(region={"x": 0.5, "theta": 0.1, "x_dot": 0.1, "theta_dot": 0.1}),
)
envs.register("Examples/CartPole-v0", TASK)
