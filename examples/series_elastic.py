"""Series-elastic (flexible) joint: a motor turns a link through a torsional spring; bring the
link to a goal angle and hold it. `examples.series_elastic:Examples/SeriesElastic-v0`.

## Description
A motor with rotor inertia J_m (reflected through its gearbox) and viscous friction b_m
drives a uniform link hanging under gravity, not rigidly but through a torsional spring of
stiffness k (Spong's flexible-joint model: a series-elastic actuator). The link's angle
answers the motor only through the spring, so it lags and oscillates. The task: bring the
link to a goal angle theta* drawn at reset and hold it still.

```
   [motor]~~~spring~~~O  joint            theta_m: motor angle (rad);
                       \\                  theta: the link's angle from the downward
                        \\  link           vertical, counter-clockwise + (rad); the spring
                                          torque is k (theta_m - theta).
```

## Action Space
`Box(-1, 1, (1,), float32)`: the motor torque tau, action 1 = `max_input` = 5 N*m
(about twice the largest gravity torque of the link). Clipped; NaN or inf raise.

## Observation Space
`Box(low, high, (9,), float32)`: cos and sin of theta and of theta_m, theta_dot and
theta_m_dot (+-30 rad/s), the goal theta* (in [-1, 1] rad) and cos, sin of theta - theta*.

## Rewards
A quadratic cost: `angle` = -(theta - theta*)^2 (wrapped, in [-pi^2, 0]), `rate` = -0.01
theta_dot^2 (in [-9, 0]), `effort` = -0.01 action^2 (in [-0.01, 0]).

## Starting State
The link and the motor at rest near hanging: theta and theta_m uniform in +-0.1 rad,
independently (the spring slightly wound); theta* uniform in [-1, 1] rad.

## Episode End
No failure region; divergence terminates with the early-end penalty. Truncation: 250
steps (5 s at 50 Hz). Success (at the last step): |theta - theta*| < 0.05 rad and
|theta_dot| < 0.2 rad/s.

## Arguments
`gymnasium.make("Examples/SeriesElastic-v0", **params)` with the model's parameters by
name: J_m (kg*m^2), b_m (N*m*s/rad), k (N*m/rad), m, l (the link's mass and length), g;
and the env's options.

## Version History
* v0: initial version.
"""

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me

import envs
from dynamics.spec import ModelSpec, Param

ID = "Examples/SeriesElastic-v0"


def series_elastic() -> ModelSpec:
    """theta_m: motor angle; theta: link angle from the downward vertical (rad, both
    counter-clockwise +). A uniform link of mass m and length l; the spring's torque on
    the link is k (theta_m - theta). Input tau: motor torque (N*m); motor friction b_m."""
    th_m, th = me.dynamicsymbols("theta_m theta")
    J_m, k, m, l, g = sp.symbols("J_m k m l g", positive=True)
    b_m = sp.Symbol("b_m", nonnegative=True)
    tau = sp.Symbol("tau")
    T = (J_m * th_m.diff() ** 2 + m * l**2 / 3 * th.diff() ** 2) / 2
    V = k * (th_m - th) ** 2 / 2 - m * g * l / 2 * sp.cos(th)
    params = {
        J_m: Param(0.05, "kg*m^2", "the motor's rotor inertia, reflected through the gear"),
        b_m: Param(0.05, "N*m*s/rad", "the motor's viscous friction", positive=False),
        k: Param(20.0, "N*m/rad", "stiffness of the spring"),
        m: Param(1.0, "kg", "mass of the link"),
        l: Param(0.5, "m", "length of the link"),
        g: Param(9.81, "m/s^2"),
    }
    return ModelSpec(
        "series_elastic", (th_m, th), T, V, params, (tau,), {th_m: tau - b_m * th_m.diff()}
    )


def holding(x, goal, p):
    """The link at rest at theta*, the motor turned ahead of it by the spring's deflection
    that carries the link's weight: theta_m = theta* + m g l sin(theta*) / (2 k)."""
    target = goal.theta_star
    return {"theta_m": target + p.m * p.g * p.l * np.sin(target) / (2 * p.k), "theta": target}


def angle(x, a, goal, p):
    e = envs.wrap(x.theta - goal.theta_star)
    return -e * e


def rate(x, a, goal, p):
    return -0.01 * x.theta_dot**2


def effort(x, a, goal, p):
    return -0.01 * a.tau**2


def success(x, a, goal, p):
    return (np.abs(envs.wrap(x.theta - goal.theta_star)) < 0.05) & (np.abs(x.theta_dot) < 0.2)


TASK = envs.Task(
    name="SeriesElastic",
    model=series_elastic,
    actuated=("tau",),
    max_input=(5.0,),
    observation=(
        envs.Angle("theta"),
        envs.Angle("theta_m"),
        envs.Value("theta_dot", unit="rad/s"),
        envs.Value("theta_m_dot", unit="rad/s"),
        envs.Value("theta*"),
        envs.AngleError("theta", "theta*"),
    ),
    terms=(
        envs.Term("angle", -(np.pi**2), 0, "-(theta - theta*)^2", angle),
        envs.Term("rate", -9.0, 0, "-0.01 theta_dot^2", rate),
        envs.Term("effort", -0.01, 0, "-0.01 action^2", effort),
    ),
    success=success,
    goal=(envs.Goal("theta*", "rad", -1.0, 1.0, doc="goal angle of the link"),),
    start={"theta_m": (-0.1, 0.1), "theta": (-0.1, 0.1)},
    limits={"theta_dot": 30.0, "theta_m_dot": 30.0},
    operating_point=holding,
    control_period=0.02,
    substeps=4,
    max_episode_steps=250,
    lqr=envs.LQRHints(
        scales={"theta": 0.05, "theta_m": 0.2, "theta_dot": 0.5, "theta_m_dot": 2.0},
        region={"theta": 0.3, "theta_m": 0.3, "theta_dot": 0.0, "theta_m_dot": 0.0},
    ),
)
envs.register(ID, TASK)
