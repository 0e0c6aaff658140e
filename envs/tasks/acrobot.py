"""Lagrange/Acrobot-v2: swing the two-link arm up with its elbow motor alone and balance it.

## Description
The two-link arm of section 7.4 (model `two_link_arm`, defaults: two uniform 1 kg, 1 m
rods) with the shoulder motor removed: only the elbow motor M2 (link 1 on link 2) acts,
with a limit of 2 m2 g l2 (9.81 N*m for the default arm): the ratio 2.0 of elbow torque to
the elbow link's gravity torque of Spong's and Drake's acrobots (the published
swing-up-and-balance setups span 2.0 to 3.8). The arm must be swung up by pumping energy,
then balanced inverted. The shoulder is free, so what the elbow can hold is limited in
kind: gravity is the only moment about the shoulder (the elbow torque acts between the
links), so every static equilibrium has the arm's mass centre on the vertical through the
shoulder, m1 l1 sin theta1 + m2 (l sin theta1 + l2 sin theta2) = 0, i.e.
sin theta2 = -3 sin theta1 for the default arm. No elbow torque holds link 1 more than
asin(1/3) = 19.5 deg off the vertical (hanging or inverted), nor the arm with its mass
centre off the shoulder's vertical; the poses it can hold need
|M2| = m2 g l2 |sin theta2| <= 4.9 N*m.

```
        A (shoulder, free)    theta1, theta2: absolute angles of the links from
        |\\                    the downward vertical, counter-clockwise positive
        | \\ theta1            (0 hangs; the goal is theta1 = theta2 = pi).
        |  C (elbow motor)
        |  |\\ theta2
           |  D (tip)
```
The goal (inverted) is fixed, so it is not observed; `goal_from_observation` returns
(pi, pi).

## Action Space
`Box(-1, 1, (1,), float32)`; action -1 and 1 are the input's limits (`max_input`,
overridable when the env is made). Actions outside [-1, 1] are clipped; NaN or inf
actions raise ValueError, complex ones TypeError.

| Num | Input | Limit | Unit |
|-----|-------|-------|------|
| 0 | M2 | 9.81 | N*m |

## Observation Space
`Box(low, high, (6,), float32)`:

| Num | Observation | Min | Max | Unit |
|-----|-------------|-----|-----|------|
| 0 | cos theta1 | -1 | 1 |  |
| 1 | sin theta1 | -1 | 1 |  |
| 2 | cos theta2 | -1 | 1 |  |
| 3 | sin theta2 | -1 | 1 |  |
| 4 | theta1_dot | -25.13 | 25.13 | rad/s |
| 5 | theta2_dot | -25.13 | 25.13 | rad/s |

## Reward terms

| Term | Min | Max | Meaning |
|---|---|---|---|
| height | -1 | 1 | tip height over reach |
| rate | -12.63 | 0 | -0.01 (theta1'^2 + theta2'^2) |
| effort | -0.001 | 0 | -0.001 action^2 |

## Rewards
On the state after the step, the sum of `height` = -(l cos theta1 + 2 l2 cos theta2) /
(l + 2 l2), the tip's height over its reach (from -1 hanging to 1 inverted), `rate` =
-0.01 (theta1'^2 + theta2'^2) and `effort` = -0.001 action^2.

## Starting State
Hanging: angles and rates uniform in [-0.1, 0.1] (rad, rad/s).
`reset(options={"state": x})` sets the state.

## Episode End
Termination: divergence, a rate beyond 8 pi rad/s or a non-finite state
(`info["diverged"]`); that step's reward adds (steps left) x (the lowest reward a step can
pay, -13.6), so ending early never pays. Truncation: 500 steps (25 s).
`info["is_success"]`: both links within 0.2 rad of inverted and both rates below 1 rad/s.

## Arguments
`gymnasium.make(id, **options)` with the env options and the parameters of `two_link_arm`
by name (each version's page on the documentation site lists them with their defaults).
Integration (`integrator="dop853"`, or `"rk4"`): 4 fixed steps of DOP853's eighth-order method
per 50 ms step (48 evaluations, chosen so that swung-up states step as accurately as with the
former RK4 x25); an unforced episode from the starting distribution keeps the energy within
1e-12 of the potential-energy range (2e-16 measured over 100 episodes,
tests/envs/test_physics.py). `num_threads` as for TwoLinkArm.

## Version History
* v2: elbow limit 2 m2 g l2 (9.81 N*m for the default arm) instead of 3 N*m, so the task is
  solvable by model-based control (trajectory optimisation + TVLQR: `python -m agents.plan
  Lagrange/Acrobot-v2`); `Lagrange/Acrobot-v1` keeps 3 N*m.
* v1: divergence terminates with the early-end penalty (v0 truncated, so diverging paid);
  built on the task declaration.
* v0: initial version.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from dynamics import wrap

from ..task import Angle, Goal, Heuristic, LQRHints, Task, Term, Value
from . import rendering
from .swing_up import swing_up_ppo

RATE_LIMIT = 8 * np.pi
"""Bound on |theta1'|, |theta2'| (rad/s): observation bound; beyond it the run diverged."""
ANGLE_TOLERANCE = 0.2
"""Success: both links within this (rad) of inverted ..."""
RATE_TOLERANCE = 1.0
"""... and both rates below this (rad/s)."""


def height(x, a, goal, p):
    """The tip's height over the arm's reach, in [-1, 1]."""
    return -(p.l * np.cos(x.theta1) + 2 * p.l2 * np.cos(x.theta2)) / (p.l + 2 * p.l2)


def rate(x, a, goal, p):
    return -0.01 * (x.theta1_dot**2 + x.theta2_dot**2)


def effort(x, a, goal, p):
    return -0.001 * a.M2**2


def success(x, a, goal, p):
    up = (np.abs(wrap(x.theta1 - goal.theta1_star)) < ANGLE_TOLERANCE) & (
        np.abs(wrap(x.theta2 - goal.theta2_star)) < ANGLE_TOLERANCE
    )
    return up & (np.abs(x.theta1_dot) < RATE_TOLERANCE) & (np.abs(x.theta2_dot) < RATE_TOLERANCE)


def draw(surface, x, g, p, history):
    rendering.draw_arm(surface, x, g, p.l, 2 * p.l2)


TASK = Task(
    name="Acrobot",
    model="two_link_arm",
    actuated=("M2",),
    max_input=(3.0,),
    observation=(
        Angle("theta1"),
        Angle("theta2"),
        Value("theta1_dot", unit="rad/s"),
        Value("theta2_dot", unit="rad/s"),
    ),
    terms=(
        Term("height", -1.0, 1.0, "tip height over reach", height),
        Term("rate", -0.02 * RATE_LIMIT**2, 0.0, "-0.01 (theta1'^2 + theta2'^2)", rate),
        Term("effort", -0.001, 0.0, "-0.001 action^2", effort),
    ),
    success=success,
    goal=(
        Goal("theta1*", "rad", np.pi, np.pi, angle=True),
        Goal("theta2*", "rad", np.pi, np.pi, angle=True),
    ),
    start={name: (-0.1, 0.1) for name in ("theta1", "theta2", "theta1_dot", "theta2_dot")},
    limits={"theta1_dot": RATE_LIMIT, "theta2_dot": RATE_LIMIT},
    operating_point={"theta1": "theta1*", "theta2": "theta2*"},
    control_period=0.05,
    substeps=4,
    integrator="dop853",
    max_episode_steps=500,
    # >= 99 % success up to 1.75x this box; the basin is a thin slab, not a small ball (no
    # 3 N*m controller recovers once the slow unstable mode, the arm leaning as a whole,
    # exceeds |w'B|/lambda; tests/agents/test_lqr.py)
    lqr=LQRHints(
        default_scale=0.1,
        region={"theta1": 0.01, "theta2": 0.01, "theta1_dot": 0.02, "theta2_dot": 0.02},
    ),
    heuristic=Heuristic("energy swing-up + LQR", "agents.control.policies:SwingUpPolicy"),
    hyperparams={"ppo": {"n_timesteps": 150_000, "gamma": 0.99}},
    draw=draw,
)
"""Acrobot-v1: the elbow limit is 3 N*m, 0.61 of the elbow link's gravity torque
(m2 g l2 = 4.9 N*m for the default arm): too small to hold link 2 horizontal, so the
swing-up must pump energy over many swings, and no published agent class is known to solve
it reliably. Kept registered to compare; Acrobot-v2 (the current version) gives the elbow
2 m2 g l2. Everything else is as described for v2."""


def elbow_limit_v2(p) -> tuple[float]:
    """Acrobot-v2's elbow limit: twice the elbow link's gravity torque m2 g l2, N*m."""
    return (2.0 * p.m2 * p.g * p.l2,)


TASK_V2 = dataclasses.replace(
    TASK,
    max_input=elbow_limit_v2,
    hyperparams={
        # PPO swings up; LQR takes over inside its basin (agents.control.handover): LQR captures
        # from 97.5 % of random directions on the level set dx' P dx = 1000, and from the
        # states within 20 x 1000 where a 3 s simulation of it succeeds. The energy shaping
        # pays for pumping towards the inverted energy: at 100, two seeds of three stayed in
        # the folded local optimum (link 2 balanced on a hanging link 1, tip height 0, a
        # quarter of the potential) where swinging costs rate penalty; at 300 none did. A
        # long horizon (gamma 0.998) and exploration (entropy, wide initial std) help too.
        # 16 copies: a batched step of 16 costs less than twice one of 8, and the runs took
        # about as many steps: in one session (10 min budget, seeds 0-2) solved after 81, 94
        # and 80 s, against 99, 267 and 112 s with 8; with 32, seed 2 stayed folded.
        "ppo": swing_up_ppo(
            3_000_000, 0.998, {"level": 1000.0, "shaping": 300.0, "verify": 3.0}, n_envs=16
        ),
        # trajectory optimisation + TVLQR (agents.plan): a 4 s swing-up from the hanging start
        "plan": {"horizon": 4.0},
    },
)
"""Acrobot-v2: TASK with the elbow limit of Spong's and Drake's acrobots (see above)."""
