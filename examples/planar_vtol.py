"""Planar VTOL (a quadrotor seen from the side): fly to a target point and hover there with two
rotors that only push. `examples.planar_vtol:Examples/PlanarVTOL-v0`.

## Description
A rigid body of mass m and moment of inertia I moves in the vertical plane under gravity,
lifted by two rotors at distance d either side of its centre, each pushing along the body's
up axis with a thrust in [0, max] (a rotor cannot pull). Tilting the body turns part of the
thrust sideways, which is the only way to move sideways (underactuated: three coordinates,
two inputs). The task: fly from near the origin to a target (x*, y*) drawn at reset and
hover there.

```
       T1 ^         ^ T2         x, y: the centre's position (m; y up);
          |__[==]__|             theta: the body's roll, counter-clockwise + (rad);
           <- d ->               the thrusts act along (-sin theta, cos theta) at
                                 -d (T1) and +d (T2) along the body's axis.
```

## Action Space
`Box(-1, 1, (2,), float32)`: the thrusts T1, T2; action -1 is no thrust, 1 is
`max_input` = m g (so the two together lift twice the weight; hovering is action 0).
Clipped; NaN or inf raise.

## Observation Space
`Box(low, high, (10,), float32)`: x, y (+-5 m), cos theta, sin theta, x_dot, y_dot (+-10
m/s), theta_dot (+-20 rad/s), the target x*, y* (in [-1, 1] m) and the errors x - x*,
y - y* (+-6 m).

## Rewards
A quadratic cost: `position` = -((x - x*)^2 + (y - y*)^2) (in [-72, 0]), `attitude` =
-theta^2 (wrapped, in [-pi^2, 0]), `speed` = -0.1 (x_dot^2 + y_dot^2) (in [-20, 0]),
`effort` = -0.01 |action|^2 (in [-0.02, 0]).

## Starting State
Hovering near the origin: x, y uniform in +-0.1 m, theta in +-0.1 rad, at rest; the target
x*, y* uniform in [-1, 1] m each.

## Episode End
Termination: |theta| > pi/2 (upside down), or divergence (|x|, |y| beyond 5 m or a rate
beyond its bound); the step then pays the early-end penalty. Truncation: 300 steps (6 s
at 50 Hz). Success (at the last step): within 0.1 m of the target, |theta| < 0.1 rad and
speeds below 0.1 m/s.

## Arguments
`gymnasium.make("Examples/PlanarVTOL-v0", **params)` with the model's parameters by name:
m (kg), I (kg*m^2), d (m), g; and the env's options (`max_input` as a pair of
`(low, high)` limits per rotor, `control_period`, ...).

## Version History
* v0: initial version.
"""

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me

import envs
from dynamics.spec import ModelSpec, Param, generalized_forces, t

ID = "Examples/PlanarVTOL-v0"
TARGETS = (-1.0, 1.0)
"""Each target coordinate is drawn uniformly from this range (m)."""


def planar_vtol() -> ModelSpec:
    """x, y: the centre of mass (m, y up); theta: roll (rad, counter-clockwise +). Inputs
    T1, T2: rotor thrusts (N) along the body's up axis at -d and +d along its axis."""
    x, y, th = me.dynamicsymbols("x y theta")
    m, I, d, g = sp.symbols("m I d g", positive=True)
    T1, T2 = sp.symbols("T1 T2")
    T = (m * (x.diff(t) ** 2 + y.diff(t) ** 2) + I * th.diff(t) ** 2) / 2
    up = sp.Matrix([-sp.sin(th), sp.cos(th)])  # the body's up axis
    axis = sp.Matrix([sp.cos(th), sp.sin(th)])
    centre = sp.Matrix([x, y])
    rotors = (centre - d * axis, centre + d * axis)
    Q = generalized_forces(
        (x, y, th), [(r.diff(t), thrust * up) for r, thrust in zip(rotors, (T1, T2))]
    )
    params = {
        m: Param(0.5, "kg"),
        I: Param(2.5e-3, "kg*m^2", "moment of inertia about the centre of mass"),
        d: Param(0.1, "m", "distance of each rotor from the centre"),
        g: Param(9.81, "m/s^2"),
    }
    return ModelSpec("planar_vtol", (x, y, th), T, m * g * y, params, (T1, T2), Q)


def hover_thrusts(p):
    return ((0.0, p.m * p.g), (0.0, p.m * p.g))


def error_x(x, a, goal, p):
    return x.x - goal.x_star


def error_y(x, a, goal, p):
    return x.y - goal.y_star


def position(x, a, goal, p):
    ex, ey = x.x - goal.x_star, x.y - goal.y_star
    return -(ex * ex + ey * ey)


def attitude(x, a, goal, p):
    e = envs.wrap(x.theta)
    return -e * e


def speed(x, a, goal, p):
    return -0.1 * (x.x_dot**2 + x.y_dot**2)


def effort(x, a, goal, p):
    return -0.01 * (a.T1**2 + a.T2**2)


def success(x, a, goal, p):
    ex, ey = x.x - goal.x_star, x.y - goal.y_star
    there = np.sqrt(ex * ex + ey * ey) < 0.1
    still = np.sqrt(x.x_dot**2 + x.y_dot**2) < 0.1
    return there & still & (np.abs(envs.wrap(x.theta)) < 0.1)


def failure(x, a, goal, p):
    return np.abs(envs.wrap(x.theta)) > np.pi / 2


TASK = envs.Task(
    name="PlanarVTOL",
    model=planar_vtol,
    actuated=("T1", "T2"),
    max_input=hover_thrusts,
    observation=(
        envs.Value("x", unit="m"),
        envs.Value("y", unit="m"),
        envs.Angle("theta"),
        envs.Value("x_dot", unit="m/s"),
        envs.Value("y_dot", unit="m/s"),
        envs.Value("theta_dot", unit="rad/s"),
        envs.Value("x*"),
        envs.Value("y*"),
        envs.Derived("x - x*", error_x, -6.0, 6.0, "m"),
        envs.Derived("y - y*", error_y, -6.0, 6.0, "m"),
    ),
    terms=(
        envs.Term("position", -72.0, 0, "-((x - x*)^2 + (y - y*)^2)", position),
        envs.Term("attitude", -(np.pi**2), 0, "-theta^2", attitude),
        envs.Term("speed", -20.0, 0, "-0.1 (x_dot^2 + y_dot^2)", speed),
        envs.Term("effort", -0.02, 0, "-0.01 |action|^2", effort),
    ),
    success=success,
    failure=failure,
    goal=(
        envs.Goal("x*", "m", *TARGETS, doc="target x"),
        envs.Goal("y*", "m", *TARGETS, doc="target height"),
    ),
    start={"x": (-0.1, 0.1), "y": (-0.1, 0.1), "theta": (-0.1, 0.1)},
    limits={"x": 5.0, "y": 5.0, "x_dot": 10.0, "y_dot": 10.0, "theta_dot": 20.0},
    operating_point={"x": "x*", "y": "y*"},
    control_period=0.02,
    substeps=2,
    max_episode_steps=300,
    lqr=envs.LQRHints(
        scales={"x": 0.5, "y": 0.5, "theta": 0.3, "x_dot": 1.0, "y_dot": 1.0, "theta_dot": 2.0},
        region={"x": 1.0, "y": 1.0, "theta": 0.1},
    ),
)
envs.register(ID, TASK)
