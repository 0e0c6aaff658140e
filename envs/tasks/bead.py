"""Lagrange/BeadOnRod-v1: hold a bead at a target distance on a motor-driven rod.

## Description
The bead of problem 7/4 on a rod that now turns freely about its pivot O (at the rod's
middle) in a vertical plane, driven by a motor (model `bead_on_driven_rod`). The task: bring
the bead to a target distance r* from O and hold it there, without letting it slide off
either end.

```
                     bead (r > 0)
                 ___o____               phi: the rod's angle above the horizontal,
        ________/  O  phi               counter-clockwise positive;
                 (pivot, motor)         r: the bead's signed distance from O along
                                        the rod, positive towards the end at phi.
```
Holding the bead at rest at r needs m g r (0.98 N*m at the end of the default rod).

## Action Space
`Box(-1, 1, (1,), float32)`; action -1 and 1 are the input's limits (`max_input`,
overridable when the env is made). Actions outside [-1, 1] are clipped; NaN or inf
actions raise ValueError, complex ones TypeError.

| Num | Input | Limit | Unit |
|-----|-------|-------|------|
| 0 | tau | 2 | N*m |

## Observation Space
`Box(low, high, (6,), float32)`:

| Num | Observation | Min | Max | Unit |
|-----|-------------|-----|-----|------|
| 0 | r | -2 | 2 | m |
| 1 | cos phi | -1 | 1 |  |
| 2 | sin phi | -1 | 1 |  |
| 3 | r_dot | -20 | 20 | m/s |
| 4 | phi_dot | -25.13 | 25.13 | rad/s |
| 5 | r* | -0.8 | 0.8 | m |

## Reward terms

| Term | Min | Max | Meaning |
|---|---|---|---|
| alive | 1 | 1 | 1 per step on the rod |
| distance | -1 | 0 | -((r - r*) / half-length)^2, at most 1 |
| precision | -1 | 0 | -\\|r - r*\\| / half-length, at most 1 |
| angle | -0.1 | 0 | -0.1 phi^2, at most 0.1 |
| effort | -0.001 | 0 | -0.001 action^2 |

## Rewards
On the state after the step, the sum of `alive` = 1, `distance` = -e^2 and `precision` =
-|e|, with e = (r - r*) / (rod_length / 2) (each at most 1: the runtime clips terms into
their bounds), `angle` = -0.1 phi^2 (phi wrapped to [-pi, pi), at most 0.1) and `effort` =
-0.001 action^2. The precision term keeps paying for the last centimetres, where the
quadratic's slope vanishes (PPO, seed 0, 50 episodes: 12-16 % success without it at 100k
steps, 26 % with it at 100k, 100 % with it at 200k).

## Starting State
r uniform within +-0.5 of the half-length, phi uniform in [-0.1, 0.1] rad, rates 0; the
target r* uniform within +-0.8 of the half-length. `reset(options={"state": x, "goal":
(r*,)})` sets them.

## Episode End
Termination: the bead leaves the rod, |r| > rod_length / 2, or divergence (a non-finite
state, |r| > rod_length or a rate beyond its bound; `info["diverged"]`); that step's reward
adds (steps left) x (the lowest reward a step can pay, -1.10), so ending early never pays.
Truncation: 200 steps (10 s). `info["is_success"]`: |r - r*| < 0.05 rod_length / 2 and
|r'| < 0.05 m/s.

## Arguments
`gymnasium.make("Lagrange/BeadOnRod-v1", control_period=0.05, substeps=1, max_input=2.0,
render_mode=None, **model_parameters)` with the parameters of `bead_on_driven_rod` by name
(m, J, rod_length, g). Integration (`integrator="dop853"`, or `"rk4"`):
one fixed step of DOP853's eighth-order method per 50 ms step (12 evaluations); an unforced
episode keeps the energy within 5e-12 of m g rod_length / 2 (1.1e-12 measured over 100
episodes, tests/envs/test_physics.py; the former RK4 x5 5e-9). `num_threads` as for
TwoLinkArm.

## Version History
* v1: leaving the rod pays the early-end penalty (v0's alive bonus alone let a falling
  bead end a bad episode early); a precision term; distance and angle terms bounded;
  built on the task declaration.
* v0: initial version.
"""

from __future__ import annotations

import numpy as np

from dynamics import wrap

from ..task import Angle, Goal, Heuristic, LQRHints, Task, Term, Value
from . import rendering

SPEED_LIMIT = 20.0
"""Bound on |r'| (m/s)."""
RATE_LIMIT = 8 * np.pi
"""Bound on |phi'| (rad/s)."""
TARGET_RANGE = 0.8
"""Targets are drawn within this fraction of the half-length of the rod."""
DISTANCE_TOLERANCE = 0.05
"""Success: |r - r*| below this fraction of the half-length ..."""
SPEED_TOLERANCE = 0.05
"""... and |r'| below this (m/s)."""


def alive(x, a, goal, p):
    return np.ones_like(x.r)


def distance(x, a, goal, p):
    e = (x.r - goal.r_star) / (p.rod_length / 2)
    return -e * e


def precision(x, a, goal, p):
    return -np.abs((x.r - goal.r_star) / (p.rod_length / 2))


def angle(x, a, goal, p):
    phi = wrap(x.phi)
    return -0.1 * phi * phi


def effort(x, a, goal, p):
    return -0.001 * a.tau**2


def success(x, a, goal, p):
    e = (x.r - goal.r_star) / (p.rod_length / 2)
    return (np.abs(e) < DISTANCE_TOLERANCE) & (np.abs(x.r_dot) < SPEED_TOLERANCE)


def failure(x, a, goal, p):
    return np.abs(x.r) > p.rod_length / 2


def start(rng, p):
    h = p.rod_length / 2
    x = {"r": rng.uniform(-0.5 * h, 0.5 * h), "phi": rng.uniform(-0.1, 0.1)}
    return x, {"r*": rng.uniform(-TARGET_RANGE * h, TARGET_RANGE * h)}


def target_low(p):
    return -TARGET_RANGE * p.rod_length / 2


def target_high(p):
    return TARGET_RANGE * p.rod_length / 2


def rod_length(p):
    return p.rod_length


def draw(surface, x, g, p, history):
    rendering.draw_bead(surface, x[0], x[1], g[0], p.rod_length)


TASK = Task(
    name="BeadOnRod",
    model="bead_on_driven_rod",
    actuated=("tau",),
    max_input=(2.0,),
    observation=(
        Value("r", unit="m"),
        Angle("phi"),
        Value("r_dot", unit="m/s"),
        Value("phi_dot", unit="rad/s"),
        Value("r*"),
    ),
    terms=(
        Term("alive", 1.0, 1.0, "1 per step on the rod", alive),
        Term("distance", -1.0, 0.0, "-((r - r*) / half-length)^2, at most 1", distance),
        Term("precision", -1.0, 0.0, "-|r - r*| / half-length, at most 1", precision),
        Term("angle", -0.1, 0.0, "-0.1 phi^2, at most 0.1", angle),
        Term("effort", -0.001, 0.0, "-0.001 action^2", effort),
    ),
    success=success,
    failure=failure,
    goal=(Goal("r*", "m", target_low, target_high),),
    start=start,
    limits={"r": rod_length, "r_dot": SPEED_LIMIT, "phi_dot": RATE_LIMIT},
    operating_point={"r": "r*"},  # the bead at rest at r* on the level rod
    control_period=0.05,
    substeps=1,
    integrator="dop853",
    max_episode_steps=200,
    # >= 99 % success up to 3.5x this region
    lqr=LQRHints(
        scales={"r": 0.1, "phi": 0.2, "r_dot": 0.1},
        region={"r": 0.1, "phi": 0.05, "r_dot": 0.1, "phi_dot": 0.1},
    ),
    heuristic=Heuristic("cascaded PD (ball and beam)", "agents.control.policies:BeadCascadePolicy"),
    hyperparams={"ppo": {"n_timesteps": 200_000}},  # 100 % success over 50 episodes, seed 0
    draw=draw,
)
