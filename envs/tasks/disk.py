"""Lagrange/RollingDisk-v1: roll a thin disk at a commanded speed and heading without falling.

## Description
The thin uniform disk of section 7.5 (model `rolling_disk`) rolls without slipping on the
horizontal floor. A drive torque acts about its axle and a steering torque about the
vertical. The task: roll at a commanded speed v* and heading phi*, drawn at reset, without
falling over.

```
      y (up)                 theta: tilt of the disk's plane from the floor, pi/2
      |    . disk            upright (the lean is theta - pi/2);
      |  /  \\  i'            phi: heading, the rolling direction is
      | |  G | --->           i' = (sin phi, 0, cos phi) in the floor's (x, z);
      |  \\  /                psi: spin about the axle; forward speed v = -r psi'.
      |___o______ x          (x, z): the contact point; x' = v sin phi,
     /  contact               z' = v cos phi (the rolling constraints).
    z
```
Upright straight rolling of this disk is self-stable when the spin exceeds sqrt(g / (3 r))
(v > 0.99 m/s for the default r = 0.3 m); slower, it must be balanced by steering. A
positive drive torque spins psi up, i.e. brakes forward rolling (v = -r psi'). The cyclic
coordinates x, z, psi are not observed (`state_from_observation` returns them as 0, with
x', z' from the rolling constraints).

## Action Space
`Box(-1, 1, (2,), float32)`; action -1 and 1 are the input's limits (`max_input`,
overridable when the env is made). Actions outside [-1, 1] are clipped; NaN or inf
actions raise ValueError, complex ones TypeError.

| Num | Input | Limit | Unit |
|-----|-------|-------|------|
| 0 | tau_drive | 0.5 | N*m |
| 1 | tau_steer | 0.1 | N*m |

## Observation Space
`Box(low, high, (13,), float32)`:

| Num | Observation | Min | Max | Unit |
|-----|-------------|-----|-----|------|
| 0 | cos theta | -1 | 1 |  |
| 1 | sin theta | -1 | 1 |  |
| 2 | cos phi | -1 | 1 |  |
| 3 | sin phi | -1 | 1 |  |
| 4 | theta_dot | -25.13 | 25.13 | rad/s |
| 5 | phi_dot | -25.13 | 25.13 | rad/s |
| 6 | psi_dot | -125.7 | 125.7 | rad/s |
| 7 | v* | -3 | 3 | m/s |
| 8 | cos phi* | -1 | 1 |  |
| 9 | sin phi* | -1 | 1 |  |
| 10 | cos(phi - phi*) | -1 | 1 |  |
| 11 | sin(phi - phi*) | -1 | 1 |  |
| 12 | v - v* | -3 | 3 | m/s |

## Reward terms

| Term | Min | Max | Meaning |
|---|---|---|---|
| alive | 1 | 1 | 1 per step |
| speed | -3 | 0 | -\\|v - v*\\|, at most 3 |
| heading | -3.142 | 0 | -\\|phi - phi*\\| |
| lean | -0.2742 | 0 | -(theta - pi/2)^2 |
| effort | -0.002 | 0 | -0.001 \\|action\\|^2 |
| track | 0 | 1 | (exp(-\\|v - v*\\| / 0.1) + exp(-\\|phi - phi*\\| / 0.1)) / 2 |

## Rewards
On the state after the step, the sum of `alive` = 1, `speed` = -|v - v*| (at most 3),
`heading` = -|phi - phi*| (wrapped to [-pi, pi)), `lean` = -(theta - pi/2)^2, `effort` =
-0.001 |action|^2 and `track` = (exp(-|v - v*| / 0.1) + exp(-|phi - phi*| / 0.1)) / 2,
which pays for precision at the scale of the success tolerances (the linear terms keep a
pull there that squared errors lose). The observation carries the tracking errors
themselves (cos and sin of phi - phi*, and v - v*) besides the absolute angles LQR reads.

## Starting State
v* uniform in [0.5, 3] m/s and phi* uniform in [-pi, pi); the disk rolls at v* with
heading phi* + U(-pi/4, pi/4), lean U(-0.05, 0.05) rad, theta', phi' U(-0.1, 0.1) rad/s, at
the origin. `reset(options={"state": x, "goal": (v*, phi*)})` sets them (a given state's
rates are projected onto the rolling constraints).

## Episode End
Termination: the lean |theta - pi/2| exceeds pi/6 (fallen), or divergence (a non-finite
state or a rate beyond its bound; `info["diverged"]`); that step's reward adds (steps left)
x (the lowest reward a step can pay, -5.42), so ending early never pays. Truncation: 400
steps (20 s). `info["is_success"]`: |v - v*| < 0.1 m/s and heading within 0.1 rad, not
fallen. `info["constraint_residual"]`: the rolling constraints' residual (m/s), at
round-off: each RK4 substep is projected back onto them.

## Arguments
`gymnasium.make("Lagrange/RollingDisk-v1", control_period=0.05, substeps=1,
max_input=(0.5, 0.1), render_mode=None, **model_parameters)` with the parameters of
`rolling_disk` by name (m, r, I, J, g). Integration (`integrator="dop853"`, or
`"rk4"`): one fixed step of DOP853's eighth-order method per 50 ms step (12 evaluations),
then a projection onto the rolling constraints; an unforced episode keeps the energy within
1e-9 of its initial value (relative; 2e-10 measured over 100 episodes,
tests/envs/test_physics.py; the former RK4 x10 2e-9). `num_threads` as for TwoLinkArm.

## Version History
* v1: falling and divergence terminate with the early-end penalty; linear speed and
  heading terms and a precision term `track`; the heading error and v - v* observed (PPO
  84 % and 94 % success at 400k steps, seeds 0 and 1, against 0 % before); built on the
  task declaration.
* v0: initial version.
"""

from __future__ import annotations

import numpy as np

from dynamics import wrap

from ..task import Angle, AngleError, Derived, Goal, LQRHints, Task, Term, Value
from . import rendering

LEAN_LIMIT = np.pi / 6
"""The episode terminates when |theta - pi/2| (the lean from upright) exceeds this (rad)."""
SPEED_RANGE = (0.5, 3.0)
"""Commanded speeds are drawn uniformly from this range (m/s)."""
TILT_RATE_LIMIT = 8 * np.pi
"""Bound on |theta'| and |phi'| (rad/s)."""
SPIN_RATE_LIMIT = 40 * np.pi
"""Bound on |psi'| (rad/s)."""
SPEED_LIMIT = 20.0
"""Bound on |x'|, |z'| (m/s)."""
SPEED_TOLERANCE = 0.1
"""Success: |v - v*| below this (m/s) ..."""
HEADING_TOLERANCE = 0.1
"""... and the heading within this (rad) of the command, upright."""
TRACK_SCALE = 0.1
"""Scale (m/s, rad) of the `track` reward term's kernels."""
SPEED_ERROR_BOUND = 3.0
"""Bound on the observed and rewarded speed error |v - v*| (m/s)."""


def speed_error(x, a, goal, p):
    """v - v* (m/s): the rolling speed -r psi' against the command; observed."""
    return -p.r * x.psi_dot - goal.v_star


def alive(x, a, goal, p):
    return np.ones_like(x.theta)


def speed(x, a, goal, p):
    return -np.abs(-p.r * x.psi_dot - goal.v_star)


def heading(x, a, goal, p):
    return -np.abs(wrap(x.phi - goal.phi_star))


def lean(x, a, goal, p):
    tilt = x.theta - 0.5 * np.pi
    return -tilt * tilt


def effort(x, a, goal, p):
    return -0.001 * (a.tau_drive**2 + a.tau_steer**2)


def track(x, a, goal, p):
    dv, dphi = np.abs(-p.r * x.psi_dot - goal.v_star), np.abs(wrap(x.phi - goal.phi_star))
    return 0.5 * (np.exp(-dv / TRACK_SCALE) + np.exp(-dphi / TRACK_SCALE))


def success(x, a, goal, p):
    speed_ok = np.abs(-p.r * x.psi_dot - goal.v_star) < SPEED_TOLERANCE
    heading_ok = np.abs(wrap(x.phi - goal.phi_star)) < HEADING_TOLERANCE
    return speed_ok & heading_ok & (np.abs(x.theta - 0.5 * np.pi) <= LEAN_LIMIT)


def failure(x, a, goal, p):
    return np.abs(x.theta - 0.5 * np.pi) > LEAN_LIMIT


def rolling_state(theta, phi, thetad, phid, speed, radius):
    """States at the origin rolling at `speed` with the given angles and rates, by name
    (the other components 0; values or arrays)."""
    return {
        "theta": theta,
        "phi": phi,
        "x_dot": speed * np.sin(phi),
        "z_dot": speed * np.cos(phi),
        "theta_dot": thetad,
        "phi_dot": phid,
        "psi_dot": -speed / radius,
    }


def start(rng, p):
    speed = rng.uniform(*SPEED_RANGE)
    heading = rng.uniform(-np.pi, np.pi)
    phi = heading + rng.uniform(-np.pi / 4, np.pi / 4)
    theta = np.pi / 2 + rng.uniform(-0.05, 0.05)
    thetad, phid = rng.uniform(-0.1, 0.1, 2)
    return rolling_state(theta, phi, thetad, phid, speed, p.r), {"v*": speed, "phi*": heading}


def upright_rolling(x, goal, p):
    """Upright straight rolling at v* along phi*: a steady motion (theta = pi/2, phi' = 0,
    psi' = -v*/r, cyclic coordinates 0); it needs no torque."""
    z = np.zeros(len(goal.v_star))
    return rolling_state(z + np.pi / 2, goal.phi_star, z, z, goal.v_star, p.r)


def spin_limit(p):
    return SPIN_RATE_LIMIT


def draw(surface, x, g, p, history):
    track = None if history is None else [(h[0], h[1]) for h in history]
    rendering.draw_disk(surface, x, g, p.r, track)


TASK = Task(
    name="RollingDisk",
    model="rolling_disk",
    actuated=("tau_drive", "tau_steer"),
    max_input=(0.5, 0.1),
    observation=(
        Angle("theta"),
        Angle("phi"),
        Value("theta_dot", unit="rad/s"),
        Value("phi_dot", unit="rad/s"),
        Value("psi_dot", unit="rad/s"),
        Value("v*"),
        Angle("phi*"),
        AngleError("phi", "phi*"),
        Derived("v - v*", speed_error, -SPEED_ERROR_BOUND, SPEED_ERROR_BOUND, "m/s"),
    ),
    terms=(
        Term("alive", 1.0, 1.0, "1 per step", alive),
        Term("speed", -SPEED_ERROR_BOUND, 0.0, "-|v - v*|, at most 3", speed),
        Term("heading", -np.pi, 0.0, "-|phi - phi*|", heading),
        Term("lean", -(LEAN_LIMIT**2), 0.0, "-(theta - pi/2)^2", lean),
        Term("effort", -0.002, 0.0, "-0.001 |action|^2", effort),
        Term("track", 0.0, 1.0, "(exp(-|v - v*| / 0.1) + exp(-|phi - phi*| / 0.1)) / 2", track),
    ),
    success=success,
    failure=failure,
    goal=(
        Goal("v*", "m/s", *SPEED_RANGE, doc="commanded speed"),
        Goal("phi*", "rad", -np.pi, np.pi, angle=True, doc="commanded heading"),
    ),
    start=start,
    limits={
        "x_dot": SPEED_LIMIT,
        "z_dot": SPEED_LIMIT,
        "theta_dot": TILT_RATE_LIMIT,
        "phi_dot": TILT_RATE_LIMIT,
        "psi_dot": spin_limit,
    },
    operating_point=upright_rolling,
    control_period=0.05,
    substeps=1,
    integrator="dop853",
    max_episode_steps=400,
    # the cyclic x, z, psi and the constrained x', z' dropped (dynamics.disk_stability);
    # >= 99 % success up to 1.6x this region (failures below the self-stable 0.99 m/s)
    lqr=LQRHints(
        states=("theta", "phi", "theta_dot", "phi_dot", "psi_dot"),
        scales={"theta": 0.05, "phi": 1.0, "psi_dot": 0.3},
        region={"theta": 0.02, "phi": 0.2, "theta_dot": 0.1, "phi_dot": 0.1, "psi_dot": 0.5},
    ),
    hyperparams={
        "ppo": {
            # a cap: the check stops once solved; its learning rate decays over the cap, and
            # 1,000,000 left the check's run unconfirmed (CHANGELOG)
            "n_timesteps": 1_500_000,
            "n_steps": 512,
            "gamma": 0.99,
            "policy_kwargs": {"net_arch": [128, 128], "log_std_init": -1.0},
        }
    },
    draw=draw,
)
