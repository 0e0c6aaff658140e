"""Double inverted pendulum on a cart: two uniform links in series on a cart pushed by a
horizontal force; balance both upright. `examples.double_cart_pole:Examples/DoubleCartPole-v0`."""

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me

import envs
from dynamics.spec import ModelSpec, Param, t


def double_cart_pole() -> ModelSpec:
    """x: cart position (m); theta1, theta2: absolute link angles from upright (rad, tipping
    right +); links of lengths 2 l1, 2 l2. Input F: horizontal force on the cart (N)."""
    x, th1, th2 = me.dynamicsymbols("x theta1 theta2")
    M, m1, m2, l1, l2, g = sp.symbols("m_cart m1 m2 l1 l2 g", positive=True)
    F = sp.Symbol("F")
    c1 = (x + l1 * sp.sin(th1), l1 * sp.cos(th1))
    c2 = (x + 2 * l1 * sp.sin(th1) + l2 * sp.sin(th2), 2 * l1 * sp.cos(th1) + l2 * sp.cos(th2))
    v2 = lambda c: c[0].diff(t) ** 2 + c[1].diff(t) ** 2  # noqa: E731
    T = (M * x.diff(t) ** 2 + m1 * v2(c1) + m2 * v2(c2)) / 2
    T += (m1 * l1**2 * th1.diff(t) ** 2 + m2 * l2**2 * th2.diff(t) ** 2) / 6  # I = m (2 l)^2 / 12
    params = {
        M: Param(1.0, "kg"),
        m1: Param(0.2, "kg"),
        m2: Param(0.2, "kg"),
        l1: Param(0.3, "m"),
        l2: Param(0.3, "m"),
        g: Param(9.81, "m/s^2"),
    }
    V = g * (m1 * c1[1] + m2 * c2[1])
    return ModelSpec("double_cart_pole", (x, th1, th2), T, V, params, (F,), {x: F})


def upright(x, a, goal, p):
    return np.cos(x.theta1) + np.cos(x.theta2)


def centre(x, a, goal, p):
    return -0.1 * (x.x / 2) ** 2


def effort(x, a, goal, p):
    return -0.001 * a.F**2


def success(x, a, goal, p):
    return (np.abs(x.theta1) < 0.05) & (np.abs(x.theta2) < 0.05) & (np.abs(x.x) < 0.1)


def failure(x, a, goal, p):
    return (np.abs(x.x) > 2.0) | (np.abs(x.theta1) > 0.6) | (np.abs(x.theta2) > 0.6)


TASK = envs.Task(
    name="DoubleCartPole",
    model=double_cart_pole,
    actuated=("F",),
    max_input=(20.0,),
    observation=(
        envs.Value("x", unit="m"),
        envs.Angle("theta1"),
        envs.Angle("theta2"),
        *(envs.Value(f"{c}_dot") for c in ("x", "theta1", "theta2")),
    ),
    terms=(
        envs.Term("upright", -2, 2, "cos theta1 + cos theta2", upright),
        envs.Term("centre", -0.4, 0, "-0.1 (x / 2)^2", centre),
        envs.Term("effort", -0.001, 0, "-0.001 action^2", effort),
    ),
    success=success,
    failure=failure,
    start={"x": (-0.2, 0.2), "theta1": (-0.05, 0.05), "theta2": (-0.05, 0.05)},
    limits={"x": 4.0, "x_dot": 10.0, "theta1_dot": 30.0, "theta2_dot": 30.0},
    operating_point={},
    control_period=0.02,
    substeps=5,
    max_episode_steps=500,
    lqr=envs.LQRHints(region={"x": 0.2, "theta1": 0.05, "theta2": 0.05}),
)
envs.register("Examples/DoubleCartPole-v0", TASK)
