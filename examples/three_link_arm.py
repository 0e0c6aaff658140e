"""Three-link arm in a vertical plane: reach a joint configuration drawn at reset and hold it
against gravity. `examples.three_link_arm:Examples/ThreeLinkArm-v0`.

## Description
Three uniform links in a chain hang from a fixed shoulder O, each driven by a motor at its
joint (the shoulder's on the base, the elbow's and the wrist's on the link before), with
viscous friction in every joint. At every reset a goal configuration (q1*, q2*, q3*) is
drawn; the arm must move there from hanging at rest and hold it: a goal-conditioned
precision task under gravity, where the motors must carry the arm's weight at the goal.

```
      O shoulder        q1: link 1 from hanging straight down, counter-clockwise + (rad)
       \\  link 1       q2: link 2 relative to link 1 (rad)
        o elbow         q3: link 3 relative to link 2 (rad)
        |  link 2
        o wrist
         \\ link 3
```

## Action Space
`Box(-1, 1, (3,), float32)`: the motor torques tau1, tau2, tau3 at the shoulder, the elbow
and the wrist, action 1 = `max_input` = (30, 15, 4) N*m (holding the arm still at a goal
needs at most 22, 9.8 and 2.5 N*m: every link horizontal). Clipped to [-1, 1].

## Observation Space
`Box(low, high, (18,), float32)`: cos and sin of q1, q2, q3, their rates (+-20 rad/s), the
goal q1*, q2*, q3*, and cos and sin of each error q_i - q_i*.

## Rewards
`angles` = -(e1^2 + e2^2 + e3^2) with e_i = q_i - q_i* wrapped (in [-3 pi^2, 0]),
`rates` = -0.01 (q1'^2 + q2'^2 + q3'^2) (in [-12, 0]) and `effort` = -0.01 |action|^2
(in [-0.03, 0]).

## Starting State
Hanging at rest: every q_i and rate uniform in +-0.05. The goal: q1* in [-1, 1], q2* and
q3* in [-1, 1] rad.

## Episode End
Divergence only (a rate beyond its bound; then the early-end penalty). Truncation: 250
steps (5 s at 50 Hz). Success (`info["is_success"]` at the last step): every joint within
0.05 rad of its goal and every joint rate below 0.1 rad/s.

## Arguments
`gymnasium.make("Examples/ThreeLinkArm-v0", **params)` with the parameters by name: m
(each link's mass), l (each link's length), b (the joints' viscous friction), g.

## Version History
* v0: initial version.
"""

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me

import envs
from dynamics.spec import ModelSpec, Param

ID = "Examples/ThreeLinkArm-v0"
ANGLE_TOLERANCE, RATE_TOLERANCE = 0.05, 0.1
"""Success: every joint within this of its goal (rad) and turning slower than this (rad/s)."""


def three_link_arm() -> ModelSpec:
    """q1: link 1 from hanging down; q2, q3: each link relative to the one before (rad,
    counter-clockwise +). Uniform links of mass m and length l; motors tau1..3 at the
    joints (N*m), viscous friction b in each."""
    q = me.dynamicsymbols("q1 q2 q3")
    m, l, g = sp.symbols("m l g", positive=True)
    b = sp.Symbol("b", nonnegative=True)
    taus = sp.symbols("tau1 tau2 tau3")
    t = me.dynamicsymbols._t
    T = V = 0
    x = y = 0  # the joint the link hangs from
    absolute = 0
    for qi in q:
        absolute = absolute + qi
        cx, cy = x + l / 2 * sp.sin(absolute), y - l / 2 * sp.cos(absolute)
        T += m * (cx.diff(t) ** 2 + cy.diff(t) ** 2) / 2 + m * l**2 / 12 * absolute.diff(t) ** 2 / 2
        V += m * g * cy
        x, y = x + l * sp.sin(absolute), y - l * sp.cos(absolute)
    # a motor between two links does virtual work tau_i dq_i (q_i is relative)
    forces = {qi: tau - b * qi.diff() for qi, tau in zip(q, taus)}
    params = {
        m: Param(1.0, "kg", "mass of each link"),
        l: Param(0.5, "m", "length of each link"),
        b: Param(0.1, "N*m*s/rad", "viscous friction of each joint", positive=False),
        g: Param(9.81, "m/s^2"),
    }
    return ModelSpec("three_link_arm", tuple(q), T, V, params, taus, forces)


def angles(x, a, goal, p):
    e1 = envs.wrap(x.q1 - goal.q1_star)
    e2 = envs.wrap(x.q2 - goal.q2_star)
    e3 = envs.wrap(x.q3 - goal.q3_star)
    return -(e1 * e1 + e2 * e2 + e3 * e3)


def rates(x, a, goal, p):
    return -0.01 * (x.q1_dot**2 + x.q2_dot**2 + x.q3_dot**2)


def effort(x, a, goal, p):
    return -0.01 * (a.tau1**2 + a.tau2**2 + a.tau3**2)


def success(x, a, goal, p):
    tol, slow = ANGLE_TOLERANCE, RATE_TOLERANCE
    near = (np.abs(envs.wrap(x.q1 - goal.q1_star)) < tol) & (
        np.abs(envs.wrap(x.q2 - goal.q2_star)) < tol
    )
    near = near & (np.abs(envs.wrap(x.q3 - goal.q3_star)) < tol)
    still = (np.abs(x.q1_dot) < slow) & (np.abs(x.q2_dot) < slow)
    return near & still & (np.abs(x.q3_dot) < slow)


TASK = envs.Task(
    name="ThreeLinkArm",
    model=three_link_arm,
    actuated=("tau1", "tau2", "tau3"),
    max_input=(30.0, 15.0, 4.0),
    observation=(
        envs.Angle("q1"),
        envs.Angle("q2"),
        envs.Angle("q3"),
        envs.Value("q1_dot", unit="rad/s"),
        envs.Value("q2_dot", unit="rad/s"),
        envs.Value("q3_dot", unit="rad/s"),
        envs.Value("q1*"),
        envs.Value("q2*"),
        envs.Value("q3*"),
        envs.AngleError("q1", "q1*"),
        envs.AngleError("q2", "q2*"),
        envs.AngleError("q3", "q3*"),
    ),
    terms=(
        envs.Term("angles", -3 * np.pi**2, 0, "-(e1^2 + e2^2 + e3^2)", angles),
        envs.Term("rates", -12.0, 0, "-0.01 (q1'^2 + q2'^2 + q3'^2)", rates),
        envs.Term("effort", -0.03, 0, "-0.01 |action|^2", effort),
    ),
    success=success,
    goal=(
        envs.Goal("q1*", "rad", -1.0, 1.0, doc="goal angle of the shoulder"),
        envs.Goal("q2*", "rad", -1.0, 1.0, doc="goal angle of the elbow"),
        envs.Goal("q3*", "rad", -1.0, 1.0, doc="goal angle of the wrist"),
    ),
    start={s: (-0.05, 0.05) for s in ("q1", "q2", "q3", "q1_dot", "q2_dot", "q3_dot")},
    limits={"q1_dot": 20.0, "q2_dot": 20.0, "q3_dot": 20.0},
    operating_point={"q1": "q1*", "q2": "q2*", "q3": "q3*"},
    control_period=0.02,
    substeps=4,
    max_episode_steps=250,
    lqr=envs.LQRHints(
        scales={"q1": 0.05, "q2": 0.05, "q3": 0.05, "q1_dot": 0.5, "q2_dot": 0.5, "q3_dot": 0.5},
        region={"q1": 0.3, "q2": 0.3, "q3": 0.3, "q1_dot": 0.0, "q2_dot": 0.0, "q3_dot": 0.0},
    ),
)
envs.register(ID, TASK)
