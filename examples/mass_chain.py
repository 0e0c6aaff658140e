"""Vibration damping: still a chain of three masses on springs, pushed at one end only.
`examples.mass_chain:Examples/MassChain-v0`.

## Description
Three carts on a straight track are joined by springs: the first to a wall and to the
second, the second to the third, each spring with a little damping (the structure rings
for many seconds). A motor pushes the first cart only. Each episode starts with the chain
deflected and moving; the task is to bring the whole chain to rest, the far cart included,
with the force on the near one: vibration suppression of a lightly damped flexible
structure through a non-collocated actuator, where success asks every cart still (speed
below 2 cm/s) as well as in place (within 5 mm).

```
  wall |/\\/\\[ m1 ]/\\/\\[ m2 ]/\\/\\[ m3 ]      x1, x2, x3: each cart from its rest position (m)
         k      <- F    k      k
```

## Action Space
`Box(-1, 1, (1,), float32)`: the force F on the first cart, action 1 = `max_input` = 5 N.

## Observation Space
`Box(low, high, (6,), float32)`: x1, x2, x3 (+-0.5 m) and their speeds (+-5 m/s).

## Rewards
`deflection` = -(x1^2 + x2^2 + x3^2) / 0.01 (in [-75, 0]), `motion` = -(x1'^2 + x2'^2 +
x3'^2) / 0.1 (in [-750, 0]), `effort` = -0.01 action^2 (in [-0.01, 0]).

## Starting State
Each cart's deflection uniform in +-0.05 m, each speed in +-0.1 m/s.

## Episode End
Termination: a cart more than 0.4 m from rest, or divergence. Truncation: 200 steps (10 s
at 20 Hz). Success (`info["is_success"]` at the last step): every cart within 5 mm of rest
and slower than 2 cm/s.

## Arguments
`gymnasium.make("Examples/MassChain-v0", **params)` with the parameters by name: m (each
cart's mass), k (each spring's stiffness), c (each spring's damping).

## Version History
* v0: initial version.
"""

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me

import envs
from dynamics.spec import ModelSpec, Param

ID = "Examples/MassChain-v0"


def mass_chain() -> ModelSpec:
    """x1, x2, x3: each cart's displacement from rest (m); springs wall-1, 1-2, 2-3 of
    stiffness k and damping c. Input F: the force on cart 1 (N)."""
    xs = me.dynamicsymbols("x1 x2 x3")
    m, k = sp.symbols("m k", positive=True)
    c = sp.Symbol("c", nonnegative=True)
    F = sp.Symbol("F")
    T = sum(m * x.diff() ** 2 for x in xs) / 2
    stretch = [xs[0], xs[1] - xs[0], xs[2] - xs[1]]
    V = sum(k * s**2 for s in stretch) / 2
    rate = [s.diff() for s in stretch]
    # each damper's force on the carts at its ends: -c d(stretch)/dt pulls them together
    forces = {
        xs[0]: F - c * rate[0] + c * rate[1],
        xs[1]: -c * rate[1] + c * rate[2],
        xs[2]: -c * rate[2],
    }
    params = {
        m: Param(1.0, "kg", "mass of each cart"),
        k: Param(50.0, "N/m", "stiffness of each spring"),
        c: Param(0.05, "N*s/m", "damping of each spring", positive=False),
    }
    return ModelSpec("mass_chain", tuple(xs), T, V, params, (F,), forces)


def deflection(x, a, goal, p):
    return -(x.x1**2 + x.x2**2 + x.x3**2) / 0.01


def motion(x, a, goal, p):
    return -(x.x1_dot**2 + x.x2_dot**2 + x.x3_dot**2) / 0.1


def effort(x, a, goal, p):
    return -0.01 * a.F**2


def success(x, a, goal, p):
    still = (np.abs(x.x1_dot) < 0.02) & (np.abs(x.x2_dot) < 0.02) & (np.abs(x.x3_dot) < 0.02)
    near = (np.abs(x.x1) < 0.005) & (np.abs(x.x2) < 0.005) & (np.abs(x.x3) < 0.005)
    return still & near


def failure(x, a, goal, p):
    return (np.abs(x.x1) > 0.4) | (np.abs(x.x2) > 0.4) | (np.abs(x.x3) > 0.4)


TASK = envs.Task(
    name="MassChain",
    model=mass_chain,
    actuated=("F",),
    max_input=(5.0,),
    observation=tuple(envs.Value(n) for n in ("x1", "x2", "x3"))
    + tuple(envs.Value(n, unit="m/s") for n in ("x1_dot", "x2_dot", "x3_dot")),
    terms=(
        envs.Term("deflection", -75.0, 0, "-(x1^2 + x2^2 + x3^2) / 0.01", deflection),
        envs.Term("motion", -750.0, 0, "-(x1'^2 + x2'^2 + x3'^2) / 0.1", motion),
        envs.Term("effort", -0.01, 0, "-0.01 action^2", effort),
    ),
    success=success,
    failure=failure,
    start={
        **{n: (-0.05, 0.05) for n in ("x1", "x2", "x3")},
        **{n: (-0.1, 0.1) for n in ("x1_dot", "x2_dot", "x3_dot")},
    },  # fmt: skip
    limits={"x1": 0.5, "x2": 0.5, "x3": 0.5, "x1_dot": 5.0, "x2_dot": 5.0, "x3_dot": 5.0},
    operating_point={},
    control_period=0.05,
    substeps=4,
    max_episode_steps=200,
    lqr=envs.LQRHints(
        scales={
            "x1": 0.005,
            "x2": 0.005,
            "x3": 0.005,
            "x1_dot": 0.02,
            "x2_dot": 0.02,
            "x3_dot": 0.02,
        },  # fmt: skip
        region={
            "x1": 0.05,
            "x2": 0.05,
            "x3": 0.05,
            "x1_dot": 0.1,
            "x2_dot": 0.1,
            "x3_dot": 0.1,
        },  # fmt: skip
    ),
)
envs.register(ID, TASK)
