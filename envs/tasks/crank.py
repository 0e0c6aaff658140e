"""Lagrange/CrankSlider-v1: move the slider of problem 7/3 to a target position and hold it.

## Description
Problem 7/3 (model `eccentric_disk_slider`): a heavy eccentric disk turns about a fixed
horizontal axle O; a massless rod PS of length l joins its pin P (at OP = R) to a particle S
sliding on a smooth horizontal line at depth h below O. A motor drives the disk. The task:
move the slider to a target position x* and hold it there.

```
              P  (pin, OP = R)
       G    /  \\                  theta: angle of OP from +x, counter-clockwise;
         \\ / th  \\  rod l         G, the disk's mass centre, at s along OP;
           O ------ \\ ----> x     x: the slider's position along its line
           : h        S            (the model's output slider_x).
   ======================== smooth line
```
Every slider position in the travel is reached at two crank angles (pin above or below the
line OS); gravity acts on the disk only, so holding the slider needs the torque
M g s cos(theta) (at most 0.98 N*m for the default disk). The slider's position and velocity
are the model's outputs `slider_x`, `slider_v`. `operating_point(obs)` regulates to rest at
the crank angle, of the two that put the slider at x*, nearest the current crank angle.

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
| 0 | cos theta | -1 | 1 |  |
| 1 | sin theta | -1 | 1 |  |
| 2 | theta_dot | -125.7 | 125.7 | rad/s |
| 3 | slider_x | -0.404 | 0.404 | m |
| 4 | slider_v | -13.39 | 13.39 | m/s |
| 5 | x* | -0.404 | 0.404 | m |

## Reward terms

| Term | Min | Max | Meaning |
|---|---|---|---|
| distance | -4 | 0 | -((x - x*) / (travel / 2))^2 |
| rate | -15.79 | 0 | -0.001 theta'^2 |
| effort | -0.001 | 0 | -0.001 action^2 |

## Rewards
On the state after the step, the sum of `distance` = -((x - x*) / (travel / 2))^2,
`rate` = -0.001 theta'^2 and `effort` = -0.001 action^2.

## Starting State
theta uniform in [-pi, pi), theta' uniform in [-0.5, 0.5] rad/s; x* uniform over the
travel less 10% at each end. `reset(options={"state": x, "goal": (x*,)})` sets them.

## Episode End
Termination: divergence, a non-finite state or |theta'| > 40 pi rad/s
(`info["diverged"]`); that step's reward adds (steps left) x (the lowest reward a step can
pay, -19.8), so ending early never pays. Truncation: 200 steps (10 s).
`info["is_success"]`: |x - x*| below 2% of the travel and |theta'| < 0.2 rad/s.

## Arguments
`gymnasium.make("Lagrange/CrankSlider-v1", control_period=0.05, substeps=4,
max_input=2.0, render_mode=None, **model_parameters)` with the parameters of
`eccentric_disk_slider` by name (I, M, m, s, R, l, h, g). Integration (`integrator="dop853"`, or
`"rk4"`): 4 fixed steps of DOP853's eighth-order method per 50 ms step (48 evaluations,
chosen so that the fastest forced states step as accurately as with the former RK4 x10);
an unforced episode keeps the energy within 3e-12 of M g |s| (7e-13 measured over 100
episodes, tests/envs/test_physics.py; 2 steps gave 3e-10). `num_threads` as for TwoLinkArm.

## Version History
* v1: divergence terminates with the early-end penalty; built on the task declaration.
* v0: initial version.
"""

from __future__ import annotations

import numpy as np

from dynamics import wrap

from ..task import Angle, Derived, Goal, Heuristic, LQRHints, Task, Term, Value
from . import rendering

RATE_LIMIT = 40 * np.pi
"""Bound on |theta'| (rad/s): observation bound; beyond it the run diverged."""
TARGET_MARGIN = 0.1
"""Targets stay this fraction of the slider's travel away from its ends."""
POSITION_TOLERANCE = 0.02
"""Success: |x - x*| below this fraction of the travel ..."""
RATE_TOLERANCE = 0.2
"""... and |theta'| below this (rad/s)."""
GRID = 720
"""Crank angles sampled to find the slider's travel and to bracket target angles."""


def distance(x, a, goal, p):
    e = (x.slider_x - goal.x_star) / p.half_travel
    return -e * e


def rate(x, a, goal, p):
    return -0.001 * x.theta_dot**2


def effort(x, a, goal, p):
    return -0.001 * a.tau**2


def success(x, a, goal, p):
    e = (x.slider_x - goal.x_star) / p.half_travel
    return (np.abs(e) < 2 * POSITION_TOLERANCE) & (np.abs(x.theta_dot) < RATE_TOLERANCE)


def slider(system, theta, rate=None):
    """The model's slider position and velocity at crank angles theta."""
    theta = np.asarray(theta, dtype=np.float64)
    x = np.stack([theta, np.zeros_like(theta) if rate is None else rate], axis=-1)
    out = system.outputs(0.0, x)
    return out["slider_x"], out["slider_v"]


def travel(system) -> dict[str, float]:
    """The slider's travel, the target range and the bounds of x, x' (constants of p)."""
    theta = np.linspace(-np.pi, np.pi, GRID, endpoint=False)
    x, dx = slider(system, theta, np.ones_like(theta))
    lo, hi = float(x.min()), float(x.max())
    margin = TARGET_MARGIN * (hi - lo)
    return {
        "half_travel": (hi - lo) / 2,
        "target_lo": lo + margin,
        "target_hi": hi - margin,
        "reach": 1.01 * float(np.abs(x).max()),
        "slider_speed": 1.01 * float(np.abs(dx).max()) * RATE_LIMIT,
    }


def rest_at_target(x, goal, p, system):
    """At rest at the crank angle, of the two that put the slider at the target, nearest
    the crank angle of x: bisection on each monotone branch between the dead centres."""
    target, near = goal.x_star, x.theta
    grid = np.linspace(-np.pi, np.pi, GRID, endpoint=False)
    xs = slider(system, grid)[0]
    roots = []
    for rising in (False, True):
        f = xs[None, :] - target[:, None]
        after = np.roll(f, -1, axis=1)
        i = ((np.sign(f) != np.sign(after)) & ((after > f) == rising)).argmax(axis=1)
        lo, hi = grid[i], grid[i] + 2 * np.pi / GRID
        for _ in range(60):  # the bracket halves each time: round-off after 60
            mid = (lo + hi) / 2
            above = (slider(system, mid)[0] > target) != rising
            lo, hi = np.where(above, mid, lo), np.where(above, hi, mid)
        roots.append((lo + hi) / 2)
    roots = np.stack(roots, axis=1)
    pick = np.abs(wrap(roots - near[:, None])).argmin(axis=1)
    theta = roots[np.arange(len(target)), pick]
    return {"theta": theta}


def slider_x(x, a, goal, p):
    return x.slider_x


def slider_v(x, a, goal, p):
    return x.slider_v


def start(rng, p):
    x = {"theta": rng.uniform(-np.pi, np.pi), "theta_dot": rng.uniform(-0.5, 0.5)}
    return x, {"x*": rng.uniform(p.target_lo, p.target_hi)}


def draw(surface, x, g, p, history):
    rendering.draw_crank(surface, x[0], x[2], g[0], p.R, p.l, p.h, p.s)


def slider_x_low(p):
    return -p.reach


def slider_v_low(p):
    return -p.slider_speed


TASK = Task(
    name="CrankSlider",
    model="eccentric_disk_slider",
    actuated=("tau",),
    max_input=(2.0,),
    observation=(
        Angle("theta"),
        Value("theta_dot", unit="rad/s"),
        Derived("slider_x", slider_x, slider_x_low, "reach", "m"),
        Derived("slider_v", slider_v, slider_v_low, "slider_speed", "m/s"),
        Value("x*", bound="reach"),
    ),
    terms=(
        Term("distance", -4.0, 0.0, "-((x - x*) / (travel / 2))^2", distance),
        Term("rate", -0.001 * RATE_LIMIT**2, 0.0, "-0.001 theta'^2", rate),
        Term("effort", -0.001, 0.0, "-0.001 action^2", effort),
    ),
    success=success,
    goal=(Goal("x*", "m", "target_lo", "target_hi", doc="slider target"),),
    start=start,
    limits={"theta_dot": RATE_LIMIT},
    outputs=("slider_x", "slider_v"),
    constants=travel,
    operating_point=rest_at_target,
    control_period=0.05,
    substeps=4,
    integrator="dop853",
    max_episode_steps=200,
    # >= 99 % success up to 32x this region (any crank angle)
    lqr=LQRHints(scales={"theta": 0.05}, region={"theta": 0.2, "theta_dot": 0.5}),
    heuristic=Heuristic("PD + gravity compensation", "agents.control.policies:GravityPDPolicy"),
    hyperparams={
        "ppo": {
            "n_timesteps": 300_000,  # a cap: the check stops once solved
            # the slider's position and its goal lie at 0.3 +- 0.05 m: scaled about zero
            # they vary by a sixth of their scale, and learning took several times as long
            "normalize": {"center": True},
        }
    },
    draw=draw,
)
