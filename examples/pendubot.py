"""Pendubot with joint friction: swing a two-link pendulum up from hanging with the shoulder
motor alone and balance it inverted. `examples.pendubot:Examples/Pendubot-v0`.

## Description
Two uniform links in series hang from a fixed shoulder O; a motor drives the shoulder
(ground on link 1), the elbow E is free (Spong's pendubot, the acrobot's sibling). Both
joints have viscous friction. The task: from hanging, bring both links upright and hold
them there.

```
          o  tip                theta1: link 1's angle from upright (absolute),
          |  link 2             counter-clockwise + (rad); theta2: link 2's angle
          E  elbow (free)       relative to link 1, counter-clockwise + (rad).
          |  link 1             Upright: theta1 = theta2 = 0; hanging: theta1 = pi,
          O  shoulder (motor)   theta2 = 0.
```

## Action Space
`Box(-1, 1, (1,), float32)`: the shoulder torque tau, action 1 = `max_input` = 2.0 N*m
(about 1.8 x the torque that holds the stretched arm horizontal). Clipped; NaN or inf raise.

## Observation Space
`Box(low, high, (6,), float32)`: cos and sin of theta1 and of theta2 (in [-1, 1]),
theta1_dot and theta2_dot (+-30 rad/s).

## Rewards
`upright` = cos theta1 + cos(theta1 + theta2), the heights of both links' directions (in
[-2, 2]); `effort` = -0.01 action^2 (in [-0.01, 0]).

## Starting State
Hanging: theta1 uniform in pi +- 0.1, theta2 and both rates uniform in +-0.1.

## Episode End
No failure region: the arm may swing freely. Divergence (a rate beyond its bound)
terminates with the early-end penalty. Truncation: 500 steps (10 s at 50 Hz). Success
(`info["is_success"]` at the last step): both links within 0.1 rad of upright
(|theta1|, |theta1 + theta2|, wrapped) and both rates below 1 rad/s.

## Arguments
`gymnasium.make("Examples/Pendubot-v0", **params)` with the model's parameters by name:
m1, m2 (kg), l1, l2 (the links' lengths, m), b1, b2 (viscous friction at the shoulder and
the elbow, N*m*s/rad), g; and the env's options (`max_input`, `control_period`, ...).
The planner's horizon (3 s) is declared: `python -m agents.plan
examples.pendubot:Examples/Pendubot-v0`.

## Learning
The task declares PPO's settings with the LQR hand-over (agents.control.handover): PPO
swings the arm up, LQR balances it once the state is inside the level set where LQR was
measured to capture (dx' P dx < 400), so `python -m agents.check
examples.pendubot:Examples/Pendubot-v0 --budget 10m` trains and scores it with no
settings. PPO without it swung up but never held both links in the 0.1 rad box (0 %:
the reward is flat there). With it (`benchmarks/learning.py`, 10 min budget, seed 0,
2026-11-25): 100 % of 20 episodes, 80 % reached after 100k steps; the agent alone 0 %, LQR
acting in 89 % of the steps. The agent brings the arm into the states where a 3 s
simulation of LQR succeeds (`verify`), not into the ellipsoid itself, and this swing-up
asks little of it: the shoulder motor is strong, and a constant 1 N*m handed over the same
way also succeeds in 20 of 20 episodes.

## Version History
* v0: initial version.
"""

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me

import envs
from dynamics.spec import ModelSpec, Param, t

ID = "Examples/Pendubot-v0"


def pendubot() -> ModelSpec:
    """theta1: link 1 from upright (absolute); theta2: link 2 relative to link 1 (rad, both
    counter-clockwise +). Uniform links of lengths l1, l2. Input tau: shoulder torque
    (N*m); viscous friction b1 at the shoulder, b2 at the elbow (on the relative rate)."""
    th1, th2 = me.dynamicsymbols("theta1 theta2")
    m1, m2, l1, l2, g = sp.symbols("m1 m2 l1 l2 g", positive=True)
    b1, b2 = sp.symbols("b1 b2", nonnegative=True)
    tau = sp.Symbol("tau")
    a2 = th1 + th2  # link 2's absolute angle
    c1 = (-l1 / 2 * sp.sin(th1), l1 / 2 * sp.cos(th1))
    c2 = (-l1 * sp.sin(th1) - l2 / 2 * sp.sin(a2), l1 * sp.cos(th1) + l2 / 2 * sp.cos(a2))

    def v2(c):
        return c[0].diff(t) ** 2 + c[1].diff(t) ** 2

    T = (m1 * v2(c1) + m2 * v2(c2)) / 2
    T += (m1 * l1**2 * th1.diff() ** 2 + m2 * l2**2 * a2.diff() ** 2) / 24  # I = m l^2 / 12
    V = g * (m1 * c1[1] + m2 * c2[1])
    forces = {th1: tau - b1 * th1.diff(), th2: -b2 * th2.diff()}
    params = {
        m1: Param(0.3, "kg", "mass of link 1"),
        m2: Param(0.2, "kg", "mass of link 2"),
        l1: Param(0.25, "m", "length of link 1"),
        l2: Param(0.25, "m", "length of link 2"),
        b1: Param(0.002, "N*m*s/rad", "viscous friction at the shoulder", positive=False),
        b2: Param(0.001, "N*m*s/rad", "viscous friction at the elbow", positive=False),
        g: Param(9.81, "m/s^2"),
    }
    return ModelSpec("pendubot", (th1, th2), T, V, params, (tau,), forces)


def upright(x, a, goal, p):
    return np.cos(x.theta1) + np.cos(x.theta1 + x.theta2)


def effort(x, a, goal, p):
    return -0.01 * a.tau**2


def success(x, a, goal, p):
    up1 = np.abs(envs.wrap(x.theta1)) < 0.1
    up2 = np.abs(envs.wrap(x.theta1 + x.theta2)) < 0.1
    still = (np.abs(x.theta1_dot) < 1.0) & (np.abs(x.theta2_dot) < 1.0)
    return up1 & up2 & still


TASK = envs.Task(
    name="Pendubot",
    model=pendubot,
    actuated=("tau",),
    max_input=(2.0,),
    observation=(
        envs.Angle("theta1"),
        envs.Angle("theta2"),
        envs.Value("theta1_dot", unit="rad/s"),
        envs.Value("theta2_dot", unit="rad/s"),
    ),
    terms=(
        envs.Term("upright", -2, 2, "cos theta1 + cos(theta1 + theta2)", upright),
        envs.Term("effort", -0.01, 0, "-0.01 action^2", effort),
    ),
    success=success,
    start={
        "theta1": (np.pi - 0.1, np.pi + 0.1),
        "theta2": (-0.1, 0.1),
        "theta1_dot": (-0.1, 0.1),
        "theta2_dot": (-0.1, 0.1),
    },
    limits={"theta1_dot": 30.0, "theta2_dot": 30.0},
    operating_point={},
    control_period=0.02,
    substeps=4,
    max_episode_steps=500,
    lqr=envs.LQRHints(
        scales={"theta1": 0.1, "theta2": 0.1, "theta1_dot": 1.0, "theta2_dot": 1.0},
        region={"theta1": 0.05, "theta2": 0.05, "theta1_dot": 0.1, "theta2_dot": 0.1},
    ),
    hyperparams={
        # PPO swings up; LQR takes over inside its basin (agents.control.handover), as on
        # Lagrange/Acrobot-v2. The level is measured (tests/examples/test_swing_up_handover.py):
        # LQR, run 10 s from random directions on the level set dx' P dx = L, captures 100 %
        # of 1000 at L = 300, 99.6 % at 400, 92.5 % of 200 at 500, 53 % at 1000. The energy
        # shaping's range is 0.3 of one episode's range of the `upright` term (500 x 4), the
        # acrobot's measured ratio (300 against 500 x 2 for its height term: at a third of
        # it, two seeds of three stayed folded, one link up and one down, where the upright
        # reward is 0 too). gamma 0.995 looks 4 s ahead, past a 3 s swing-up (the plan's
        # horizon); the rest of the settings are the acrobot's (envs.tasks.swing_up). n_timesteps
        # also sets how often a --budget run evaluates (every 30th: 50k steps). At 500k
        # (every 16.7k) a pendubot run evaluated 100, 75, 90, 50 % at 16.7k-66.7k steps:
        # no two in a row at 80 %.
        "ppo": envs.swing_up_ppo(
            1_500_000, 0.995, {"level": 400.0, "shaping": 600.0, "verify": 3.0}
        ),
        "plan": {"horizon": 3.0},
    },
)
envs.register(ID, TASK)
