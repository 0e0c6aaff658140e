"""Lagrange/TwoLinkArm-v1: drive the fully actuated two-link arm to a goal configuration.

## Description
The planar two-link arm of section 7.4 (model `two_link_arm`) hangs from a fixed shoulder A
under gravity, with a motor at the shoulder (ground on link 1) and one at the elbow C (link
1 on link 2). The task: bring the arm to a goal configuration drawn at reset anywhere on the
torus of configurations, inverted ones included, and hold it.

```
        A (shoulder)          theta1, theta2: absolute angles of the links from
        |\\                    the downward vertical, counter-clockwise positive
        | \\ theta1            (0 hangs, pi is inverted).
        |  C (elbow)
        |  |\\ theta2
           |  D (tip)
```
The default input limits are 1.5 times the largest static holding torques,
(m1 l1 + m2 l) g + m2 l2 g and m2 l2 g: 29.4 and 7.4 N*m for the default arm, so any
configuration can be held. The goal angles theta1*, theta2* are observed through cos and
sin, and so are the wrapped goal errors, so that a policy need not learn angle differences.

## Action Space
`Box(-1, 1, (2,), float32)`; action -1 and 1 are the input's limits (`max_input`,
overridable when the env is made). Actions outside [-1, 1] are clipped; NaN or inf
actions raise ValueError, complex ones TypeError.

| Num | Input | Limit | Unit |
|-----|-------|-------|------|
| 0 | M1 | 29.43 | N*m |
| 1 | M2 | 7.357 | N*m |

## Observation Space
`Box(low, high, (14,), float32)`:

| Num | Observation | Min | Max | Unit |
|-----|-------------|-----|-----|------|
| 0 | cos theta1 | -1 | 1 |  |
| 1 | sin theta1 | -1 | 1 |  |
| 2 | cos theta2 | -1 | 1 |  |
| 3 | sin theta2 | -1 | 1 |  |
| 4 | theta1_dot | -25.13 | 25.13 | rad/s |
| 5 | theta2_dot | -25.13 | 25.13 | rad/s |
| 6 | cos theta1* | -1 | 1 |  |
| 7 | sin theta1* | -1 | 1 |  |
| 8 | cos theta2* | -1 | 1 |  |
| 9 | sin theta2* | -1 | 1 |  |
| 10 | cos(theta1 - theta1*) | -1 | 1 |  |
| 11 | sin(theta1 - theta1*) | -1 | 1 |  |
| 12 | cos(theta2 - theta2*) | -1 | 1 |  |
| 13 | sin(theta2 - theta2*) | -1 | 1 |  |

## Reward terms

| Term | Min | Max | Meaning |
|---|---|---|---|
| angle | -19.74 | 0 | -(e1^2 + e2^2) |
| precision | -4.443 | 0 | -sqrt(e1^2 + e2^2) |
| rate | -12.63 | 0 | -0.01 (theta1'^2 + theta2'^2) |
| effort | -0.002 | 0 | -0.001 \\|action\\|^2 |

## Rewards
On the state after the step, the sum of `angle` = -(e1^2 + e2^2) with e = theta - theta*
wrapped to [-pi, pi); `precision` = -sqrt(e1^2 + e2^2), whose slope does not vanish at the
goal as the quadratic's does; `rate` = -0.01 (theta1'^2 + theta2'^2); `effort` = -0.001
|action|^2.

## Starting State
Angles uniform in [-pi, pi), rates uniform in [-0.1, 0.1] rad/s, the goal angles uniform
in [-pi, pi). `reset(options={"state": x, "goal": (theta1*, theta2*)})` sets them.

## Episode End
Termination: divergence, a rate beyond 8 pi rad/s or a non-finite state (`info["diverged"]`);
that step's reward adds (steps left) x (the lowest reward a step can pay, -36.8), so ending
early never pays. Truncation: 200 steps (10 s). `info["is_success"]`: both wrapped angle
errors below 0.1 rad and both rates below 0.5 rad/s.

## Arguments
`gymnasium.make("Lagrange/TwoLinkArm-v1", control_period=0.05, substeps=6,
max_input=None, render_mode=None, **model_parameters)` with the parameters of
`two_link_arm` by name (m1, m2, l, l1, l2, Ibar1, Ibar2, g). Integration
(`integrator="dop853"`, or `"rk4"`): 6 fixed steps of DOP853's eighth-order method per 50 ms
step (72 derivative evaluations); an unforced episode from the starting distribution keeps
the energy within 3e-8 of the potential-energy range, inverted minus hanging (9e-9 measured
over 100 episodes, tests/envs/test_physics.py; 4 steps gave 1e-6, the former RK4 x25 3e-7).
`num_threads` (default 1) spreads a vector env's copies over threads with the same result
bit for bit.

## Version History
* v1: divergence terminates with the early-end penalty (v0 truncated, so diverging paid);
  observation reordered to (cos, sin) per angle; built on the task declaration.
* v0: initial version.
"""

from __future__ import annotations

import numpy as np

from dynamics import wrap

from ..task import Angle, AngleError, Goal, Heuristic, LQRHints, Task, Term, Value
from . import rendering

RATE_LIMIT = 8 * np.pi
"""Bound on |theta1'|, |theta2'| (rad/s): observation bound; beyond it the run diverged."""
ANGLE_TOLERANCE = 0.1
"""Success: both wrapped angle errors below this (rad) ..."""
RATE_TOLERANCE = 0.5
"""... and both rates below this (rad/s)."""


def angle(x, a, goal, p):
    e1, e2 = wrap(x.theta1 - goal.theta1_star), wrap(x.theta2 - goal.theta2_star)
    return -(e1 * e1 + e2 * e2)


def precision(x, a, goal, p):
    e1, e2 = wrap(x.theta1 - goal.theta1_star), wrap(x.theta2 - goal.theta2_star)
    return -np.sqrt(e1 * e1 + e2 * e2)


def rate(x, a, goal, p):
    return -0.01 * (x.theta1_dot * x.theta1_dot + x.theta2_dot * x.theta2_dot)


def effort(x, a, goal, p):
    return -0.001 * (a.M1**2 + a.M2**2)


def success(x, a, goal, p):
    near = (np.abs(wrap(x.theta1 - goal.theta1_star)) < ANGLE_TOLERANCE) & (
        np.abs(wrap(x.theta2 - goal.theta2_star)) < ANGLE_TOLERANCE
    )
    return near & (np.abs(x.theta1_dot) < RATE_TOLERANCE) & (np.abs(x.theta2_dot) < RATE_TOLERANCE)


def holding_torques(p):
    """1.5 x the largest static holding torques of the shoulder and the elbow, N*m."""
    shoulder = (p.m1 * p.l1 + p.m2 * p.l) * p.g + p.m2 * p.l2 * p.g
    return 1.5 * shoulder, 1.5 * p.m2 * p.l2 * p.g


def draw(surface, x, g, p, history):
    rendering.draw_arm(surface, x, g, p.l, 2 * p.l2)


TASK = Task(
    name="TwoLinkArm",
    model="two_link_arm",
    actuated=("M1", "M2"),
    max_input=holding_torques,
    observation=(
        Angle("theta1"),
        Angle("theta2"),
        Value("theta1_dot", unit="rad/s"),
        Value("theta2_dot", unit="rad/s"),
        Angle("theta1*"),
        Angle("theta2*"),
        AngleError("theta1", "theta1*"),
        AngleError("theta2", "theta2*"),
    ),
    terms=(
        Term("angle", -2 * np.pi**2, 0.0, "-(e1^2 + e2^2)", angle),
        Term("precision", -np.sqrt(2) * np.pi, 0.0, "-sqrt(e1^2 + e2^2)", precision),
        Term("rate", -0.02 * RATE_LIMIT**2, 0.0, "-0.01 (theta1'^2 + theta2'^2)", rate),
        Term("effort", -0.002, 0.0, "-0.001 |action|^2", effort),
    ),
    success=success,
    goal=(
        Goal("theta1*", "rad", -np.pi, np.pi, angle=True),
        Goal("theta2*", "rad", -np.pi, np.pi, angle=True),
    ),
    start={
        "theta1": (-np.pi, np.pi),
        "theta2": (-np.pi, np.pi),
        "theta1_dot": (-0.1, 0.1),
        "theta2_dot": (-0.1, 0.1),
    },
    limits={"theta1_dot": RATE_LIMIT, "theta2_dot": RATE_LIMIT},
    operating_point={"theta1": "theta1*", "theta2": "theta2*"},
    control_period=0.05,
    substeps=6,
    integrator="dop853",
    max_episode_steps=200,
    # measured (seed 0, 100 episodes): >= 99 % success up to 12x this region
    lqr=LQRHints(
        scales={"theta1": 0.05, "theta2": 0.05},
        region={"theta1": 0.3, "theta2": 0.3, "theta1_dot": 0.5, "theta2_dot": 0.5},
    ),
    heuristic=Heuristic("PD + gravity compensation", "agents.control.policies:GravityPDPolicy"),
    hyperparams={
        # 1M steps, 50 evaluation episodes, seeds 0, 1, 2: 90, 96, 94 % success (v0). With 8
        # copies, n_steps 512, gamma 0.99: 46 %.
        "ppo": {
            "n_timesteps": 1_000_000,
            "n_envs": 16,
            "batch_size": 512,
            "policy_kwargs": {"net_arch": [128, 128], "log_std_init": -1.0},
        }
    },
    draw=draw,
)
