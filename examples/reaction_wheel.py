"""Reaction-wheel pendulum: balance an inverted pendulum with the torque of a wheel it carries.
`examples.reaction_wheel:Examples/ReactionWheel-v0`.

## Description
A rod hangs from a fixed frictionless pivot O and carries at its tip a wheel spun by a
motor mounted on the rod. The motor's torque accelerates the wheel one way and the rod the
other: the only means of holding the rod upright (an underactuated balance task, as on
Block and Spong's reaction-wheel pendulum). The wheel's bearing has viscous friction.

```
        ( W )  wheel, spin phi relative to the rod    theta: rod angle from upright,
          |                                           counter-clockwise + (rad);
          |  rod                                      phi: wheel angle relative to the rod,
          |                                           counter-clockwise + (rad).
          O  pivot
```

## Action Space
`Box(-1, 1, (1,), float32)`: the motor torque tau on the wheel (the rod feels -tau),
action 1 = `max_input` = 0.4 N*m. Clipped to [-1, 1]; NaN or inf raise.

## Observation Space
`Box(low, high, (4,), float32)`: cos theta, sin theta (in [-1, 1]), theta_dot (+-20
rad/s), phi_dot (+-300 rad/s, the wheel's speed relative to the rod). The wheel angle phi
is cyclic and not observed.

## Rewards
A quadratic cost: `angle` = -theta^2 (theta wrapped, in [-pi^2, 0]), `rate` = -0.01
theta_dot^2 (in [-4, 0]) and `effort` = -0.01 action^2 (in [-0.01, 0]).

## Starting State
theta and theta_dot uniform in +-0.2 (rad, rad/s), the wheel at rest relative to the rod.

## Episode End
Termination: |theta| > 0.5 rad (fallen) or divergence (a rate beyond its bound); the step
then pays the early-end penalty (steps left x the lowest reward a step can pay).
Truncation: 500 steps (10 s at 50 Hz). Success (`info["is_success"]` at the last step):
|theta| < 0.05 rad and |theta_dot| < 0.2 rad/s.

## Arguments
`gymnasium.make("Examples/ReactionWheel-v0", **params)` with the model's parameters by
name: m_rod, l_rod (the rod's length), m_wheel, I_wheel (the wheel's spin inertia),
b_wheel (the bearing's viscous friction, N*m*s/rad), g; and the env's options
(`max_input`, `control_period`, `substeps`, `randomize`, `perturb`).

## Version History
* v0: initial version.
"""

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me

import envs
from dynamics.spec import ModelSpec, Param

ID = "Examples/ReactionWheel-v0"


def reaction_wheel() -> ModelSpec:
    """theta: rod angle from upright; phi: wheel angle relative to the rod (rad, both
    counter-clockwise +). A uniform rod of length L and mass m_r, a wheel (mass m_w, spin
    inertia I_w) centred at its tip. Input tau: motor torque, rod on wheel (N*m)."""
    th, ph = me.dynamicsymbols("theta phi")
    m_r, L, m_w, I_w, g = sp.symbols("m_rod l_rod m_wheel I_wheel g", positive=True)
    b = sp.Symbol("b_wheel", nonnegative=True)
    tau = sp.Symbol("tau")
    # rod about its pivot m L^2 / 3, the wheel's centre at the tip, its spin absolute
    T = (m_r * L**2 / 3 + m_w * L**2) * th.diff() ** 2 / 2
    T += I_w * (th.diff() + ph.diff()) ** 2 / 2
    V = (m_r * L / 2 + m_w * L) * g * sp.cos(th)
    # the motor acts between rod and wheel: virtual work tau * dphi (phi is relative),
    # the bearing's friction the same way
    forces = {ph: tau - b * ph.diff()}
    params = {
        m_r: Param(0.2, "kg", "mass of the rod"),
        L: Param(0.2, "m", "length of the rod (pivot to wheel centre)"),
        m_w: Param(0.3, "kg", "mass of the wheel"),
        I_w: Param(1.5e-3, "kg*m^2", "the wheel's moment of inertia about its axle"),
        b: Param(1e-4, "N*m*s/rad", "viscous friction of the wheel's bearing", positive=False),
        g: Param(9.81, "m/s^2"),
    }
    return ModelSpec("reaction_wheel", (th, ph), T, V, params, (tau,), forces)


def angle(x, a, goal, p):
    e = envs.wrap(x.theta)
    return -e * e


def rate(x, a, goal, p):
    return -0.01 * x.theta_dot**2


def effort(x, a, goal, p):
    return -0.01 * a.tau**2


def success(x, a, goal, p):
    return (np.abs(envs.wrap(x.theta)) < 0.05) & (np.abs(x.theta_dot) < 0.2)


def failure(x, a, goal, p):
    return np.abs(envs.wrap(x.theta)) > 0.5


TASK = envs.Task(
    name="ReactionWheel",
    model=reaction_wheel,
    actuated=("tau",),
    max_input=(0.4,),
    observation=(
        envs.Angle("theta"),
        envs.Value("theta_dot", unit="rad/s"),
        envs.Value("phi_dot", unit="rad/s"),
    ),
    terms=(
        envs.Term("angle", -(np.pi**2), 0, "-theta^2", angle),
        envs.Term("rate", -4.0, 0, "-0.01 theta_dot^2", rate),
        envs.Term("effort", -0.01, 0, "-0.01 action^2", effort),
    ),
    success=success,
    failure=failure,
    start={"theta": (-0.2, 0.2), "theta_dot": (-0.2, 0.2)},
    limits={"theta_dot": 20.0, "phi_dot": 300.0},
    operating_point={},
    control_period=0.02,
    substeps=4,
    max_episode_steps=500,
    # phi is cyclic (nothing depends on it): LQR keeps the rest
    lqr=envs.LQRHints(
        states=("theta", "theta_dot", "phi_dot"),
        scales={"theta": 0.05, "theta_dot": 0.5, "phi_dot": 100.0},
        region={"theta": 0.2, "theta_dot": 0.2, "phi_dot": 0.0},
    ),
)
envs.register(ID, TASK)
