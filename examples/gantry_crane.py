"""Gantry crane: move a trolley carrying a load on a rope to a target and stop it there
without the load swinging. `examples.gantry_crane:Examples/GantryCrane-v0`.

## Description
A trolley runs on a horizontal rail, pushed by a motor's force F against viscous rolling
friction; a load hangs from it on a rope of fixed length (a pendulum on a carriage). The
task: carry the load to a target position x* drawn at reset and bring it to rest there.

```
   ====[trolley]=================== rail       x: trolley position (m, right +);
           \\                                   phi: rope angle from the downward
            \\ rope, length l                   vertical, counter-clockwise + (the
             (load)                             load swings right for phi > 0).
```

## Action Space
`Box(-1, 1, (1,), float32)`: the force F on the trolley, action 1 = `max_input` = 20 N.
Clipped; NaN or inf raise.

## Observation Space
`Box(low, high, (7,), float32)`: x (+-3 m), cos phi, sin phi, x_dot (+-5 m/s), phi_dot
(+-10 rad/s), the target x* (in [-2, 2] m) and the error x - x* (+-5 m).

## Rewards
A quadratic cost: `position` = -(x - x*)^2 (in [-25, 0]), `swing` = -phi^2 (phi wrapped,
in [-pi^2, 0]), `speed` = -0.1 x_dot^2 (in [-2.5, 0]), `effort` = -0.01 action^2.

## Starting State
The trolley at rest at x uniform in +-0.2 m, the load hanging (phi uniform in +-0.05 rad);
the target x* uniform in [-2, 2] m.

## Episode End
Termination: the trolley beyond the rail's ends |x| > 2.5 m, or divergence; the step then
pays the early-end penalty. Truncation: 400 steps (20 s at 20 Hz). Success (at the last
step): |x - x*| < 0.05 m, |phi| < 0.05 rad, |x_dot| < 0.05 m/s and |phi_dot| < 0.1 rad/s.

## Arguments
`gymnasium.make("Examples/GantryCrane-v0", **params)` with the model's parameters by
name: m_trolley, m_load (kg), l (rope length, m), c (the trolley's viscous friction,
N*s/m), g; and the env's options.

## Version History
* v0: initial version.
"""

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me

import envs
from dynamics.spec import ModelSpec, Param, t

ID = "Examples/GantryCrane-v0"
RAIL = 2.5
"""The trolley leaves the rail beyond |x| = RAIL (m)."""
TARGETS = (-2.0, 2.0)
"""Targets x* are drawn uniformly from this range (m)."""


def gantry_crane() -> ModelSpec:
    """x: trolley position (m); phi: rope angle from the downward vertical (rad, the load
    swings to +x for phi > 0); a point load on a massless rope of length l. Input F:
    horizontal force on the trolley (N); viscous friction c on the trolley."""
    x, phi = me.dynamicsymbols("x phi")
    M, m, l, g = sp.symbols("m_trolley m_load l g", positive=True)
    c = sp.Symbol("c", nonnegative=True)
    F = sp.Symbol("F")
    px, py = x + l * sp.sin(phi), -l * sp.cos(phi)  # the load
    T = (M * x.diff(t) ** 2 + m * (px.diff(t) ** 2 + py.diff(t) ** 2)) / 2
    V = m * g * py
    params = {
        M: Param(5.0, "kg", "mass of the trolley"),
        m: Param(2.0, "kg", "mass of the load"),
        l: Param(1.0, "m", "length of the rope"),
        c: Param(2.0, "N*s/m", "viscous friction of the trolley", positive=False),
        g: Param(9.81, "m/s^2"),
    }
    return ModelSpec("gantry_crane", (x, phi), T, V, params, (F,), {x: F - c * x.diff(t)})


def error(x, a, goal, p):
    return x.x - goal.x_star


def position(x, a, goal, p):
    e = x.x - goal.x_star
    return -e * e


def swing(x, a, goal, p):
    e = envs.wrap(x.phi)
    return -e * e


def speed(x, a, goal, p):
    return -0.1 * x.x_dot**2


def effort(x, a, goal, p):
    return -0.01 * a.F**2


def success(x, a, goal, p):
    there = (np.abs(x.x - goal.x_star) < 0.05) & (np.abs(envs.wrap(x.phi)) < 0.05)
    return there & (np.abs(x.x_dot) < 0.05) & (np.abs(x.phi_dot) < 0.1)


def failure(x, a, goal, p):
    return np.abs(x.x) > RAIL


TASK = envs.Task(
    name="GantryCrane",
    model=gantry_crane,
    actuated=("F",),
    max_input=(20.0,),
    observation=(
        envs.Value("x", unit="m"),
        envs.Angle("phi"),
        envs.Value("x_dot", unit="m/s"),
        envs.Value("phi_dot", unit="rad/s"),
        envs.Value("x*"),
        envs.Derived("x - x*", error, -5.0, 5.0, "m"),
    ),
    terms=(
        envs.Term("position", -25.0, 0, "-(x - x*)^2", position),
        envs.Term("swing", -(np.pi**2), 0, "-phi^2", swing),
        envs.Term("speed", -2.5, 0, "-0.1 x_dot^2", speed),
        envs.Term("effort", -0.01, 0, "-0.01 action^2", effort),
    ),
    success=success,
    failure=failure,
    goal=(envs.Goal("x*", "m", *TARGETS, doc="target position of the trolley"),),
    start={"x": (-0.2, 0.2), "phi": (-0.05, 0.05)},
    limits={"x": 3.0, "x_dot": 5.0, "phi_dot": 10.0},
    operating_point={"x": "x*"},
    control_period=0.05,
    substeps=5,
    max_episode_steps=400,
    lqr=envs.LQRHints(
        scales={"x": 0.5, "phi": 0.1, "x_dot": 0.5, "phi_dot": 0.5},
        region={"x": 0.5, "phi": 0.05, "x_dot": 0.0, "phi_dot": 0.0},
    ),
)
envs.register(ID, TASK)
