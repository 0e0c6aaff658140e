"""Spacecraft slew: turn a free-floating body to an attitude drawn at reset with the
torque of a reaction wheel, and stop there. `examples.slew:Examples/Slew-v0`.

## Description
A rigid body floats free in a plane (no gravity, no pivot torque) and carries a reaction
wheel on an axle at its centre, spun by a motor on the body (the bearing's viscous
friction b_wheel is 0 by default). The motor's torque turns the wheel one way and the body
the other, so the body turns only by exchanging momentum with the wheel. At every reset a
goal attitude theta* is drawn; the body starts nearly at rest and must turn there and
**stop**: success asks the attitude within 0.02 rad and the body's rate below 0.01 rad/s,
a rest-to-rest slew whose success set is as tight on the rate as on the position.

```
   +-------+
   |  (W)  |   body (attitude theta, counter-clockwise +), wheel W at its centre
   +-------+   phi: the wheel's angle relative to the body
```

## Action Space
`Box(-1, 1, (1,), float32)`: the motor torque tau on the wheel (the body feels -tau),
action 1 = `max_input` = 0.1 N*m.

## Observation Space
`Box(low, high, (7,), float32)`: cos theta, sin theta, theta_dot (+-5 rad/s), phi_dot
(+-300 rad/s, the wheel's speed relative to the body), the goal theta*, and cos and sin
of the error theta - theta*.

## Rewards
`attitude` = -|theta - theta*| / pi (wrapped, in [-1, 0]), `rate` = -0.1 |theta_dot| (in
[-0.5, 0]), `effort` = -0.01 action^2 (in [-0.01, 0]).

## Starting State
theta uniform in +-0.1 rad, theta_dot in +-0.02 rad/s, the wheel at rest relative to the
body; the goal theta* uniform in [-1, 1] rad.

## Episode End
Divergence only (a rate beyond its bound). Truncation: 300 steps (15 s at 20 Hz). Success
(`info["is_success"]` at the last step): |theta - theta*| < 0.02 rad and |theta_dot| <
0.01 rad/s.

## Arguments
`gymnasium.make("Examples/Slew-v0", **params)` with the parameters by name: I_body,
I_wheel, b_wheel.

## Version History
* v0: initial version.
"""

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me

import envs
from dynamics.spec import ModelSpec, Param

ID = "Examples/Slew-v0"


def slew() -> ModelSpec:
    """theta: the body's attitude; phi: the wheel's angle relative to the body (rad,
    counter-clockwise +). Input tau: the motor's torque, body on wheel (N*m)."""
    th, ph = me.dynamicsymbols("theta phi")
    I_b, I_w = sp.symbols("I_body I_wheel", positive=True)
    b = sp.Symbol("b_wheel", nonnegative=True)
    tau = sp.Symbol("tau")
    T = I_b * th.diff() ** 2 / 2 + I_w * (th.diff() + ph.diff()) ** 2 / 2
    params = {
        I_b: Param(0.5, "kg*m^2", "the body's moment of inertia (the wheel's mass included)"),
        I_w: Param(0.01, "kg*m^2", "the wheel's moment of inertia about its axle"),
        b: Param(0.0, "N*m*s/rad", "viscous friction of the wheel's bearing", positive=False),
    }
    return ModelSpec("slew", (th, ph), T, 0, params, (tau,), {ph: tau - b * ph.diff()})


def attitude(x, a, goal, p):
    return -np.abs(envs.wrap(x.theta - goal.theta_star)) / np.pi


def rate(x, a, goal, p):
    return -0.1 * np.abs(x.theta_dot)


def effort(x, a, goal, p):
    return -0.01 * a.tau**2


def success(x, a, goal, p):
    return (np.abs(envs.wrap(x.theta - goal.theta_star)) < 0.02) & (np.abs(x.theta_dot) < 0.01)


TASK = envs.Task(
    name="Slew",
    model=slew,
    actuated=("tau",),
    max_input=(0.1,),
    observation=(
        envs.Angle("theta"),
        envs.Value("theta_dot", unit="rad/s"),
        envs.Value("phi_dot", unit="rad/s"),
        envs.Value("theta*"),
        envs.AngleError("theta", "theta*"),
    ),
    terms=(
        envs.Term("attitude", -1.0, 0, "-|theta - theta*| / pi", attitude),
        envs.Term("rate", -0.5, 0, "-0.1 |theta_dot|", rate),
        envs.Term("effort", -0.01, 0, "-0.01 action^2", effort),
    ),
    success=success,
    goal=(envs.Goal("theta*", "rad", -1.0, 1.0, angle=True, doc="attitude to turn to"),),
    start={"theta": (-0.1, 0.1), "theta_dot": (-0.02, 0.02)},
    limits={"theta_dot": 5.0, "phi_dot": 300.0},
    operating_point={"theta": "theta*"},
    control_period=0.05,
    substeps=2,
    max_episode_steps=300,
    # the body and wheel's total angular momentum is conserved (no outside torque): no
    # input changes it, so LQR keeps the body's attitude and rate alone (with friction in
    # the bearing the wheel's speed drives the body's rate, and LQR would refuse the task)
    lqr=envs.LQRHints(
        states=("theta", "theta_dot"),
        scales={"theta": 0.02, "theta_dot": 0.01},
        region={"theta": 0.3, "theta_dot": 0.02},
    ),
)
envs.register(ID, TASK)
