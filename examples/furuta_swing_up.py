"""Furuta pendulum swung up from hanging: the model and task of furuta.py, with the start
hanging and no failure region. `examples.furuta_swing_up:Examples/FurutaSwingUp-v0`.

## Description
A motor turns a horizontal arm about the vertical; a pendulum (a uniform rod) swings across
the arm's tip. From hanging, swing the pendulum up and balance it upright. The model,
angles and parameters are furuta.py's: alpha, the arm's angle about the vertical
(counter-clockwise from above); theta, the pendulum's angle from upright about the arm.

## Action Space
`Box(-1, 1, (1,), float32)`: the motor torque tau on the arm, action 1 = `max_input` =
0.5 N*m. Clipped to [-1, 1]; NaN or inf raise.

## Observation Space
`Box(low, high, (6,), float32)`: cos and sin of alpha and of theta (in [-1, 1]),
alpha_dot and theta_dot (+-40 rad/s).

## Rewards
`upright` = cos theta (in [-1, 1]), `arm` = -0.1 alpha^2 (alpha wrapped, in
[-0.1 pi^2, 0]) and `effort` = -0.01 action^2 (in [-0.01, 0]).

## Starting State
Hanging: theta uniform in pi +- 0.1, alpha and theta_dot uniform in +-0.1, alpha_dot 0.

## Episode End
No failure region: the pendulum may swing freely. Divergence (a rate beyond its bound)
terminates with the early-end penalty. Truncation: 500 steps (10 s at 50 Hz). Success
(`info["is_success"]` at the last step): theta within 0.05 rad of upright and both rates
below 0.3 rad/s.

## Arguments
`gymnasium.make("Examples/FurutaSwingUp-v0", **params)` with furuta.py's parameters by
name (J, m, r, l, g) and the env's options (`max_input`, `control_period`, ...). The
planner's horizon (3 s) is declared: `python -m agents.plan
examples.furuta_swing_up:Examples/FurutaSwingUp-v0` (trajectory optimisation + TVLQR).

## Learning
The task declares PPO's settings with the LQR hand-over (agents.control.handover): PPO
swings the pendulum up, LQR balances it once the state is inside the level set where LQR
was measured to capture (dx' P dx < 50), so `python -m agents.check
examples.furuta_swing_up:Examples/FurutaSwingUp-v0 --budget 10m` trains and scores it with
no settings. PPO without it reached a return of about 111 and 0 %. With it
(`benchmarks/learning.py`, 10 min budget, seed 0, 2026-11-25): 95 % of 20 episodes, 80 %
reached after 250k steps; the agent alone 0 %, LQR acting in 89 % of the steps (from the
states its 3 s check verifies, a median 0.6 s after the start). A constant torque (zero,
or the full torque either way) handed over the same way succeeds in none.

## Version History
* v0: initial version.
"""

import dataclasses

import numpy as np

import envs
from examples import furuta

TASK = dataclasses.replace(
    furuta.TASK,
    name="FurutaSwingUp",
    failure=None,
    start={"alpha": (-0.1, 0.1), "theta": (np.pi - 0.1, np.pi + 0.1), "theta_dot": (-0.1, 0.1)},
    hyperparams={
        # PPO swings up; LQR takes over inside its basin (agents.control.handover), as on
        # Lagrange/Acrobot-v2. The level is measured (tests/examples/test_swing_up_handover.py):
        # LQR, run 10 s from random directions on the level set dx' P dx = L, captures 100 %
        # of 1000 at L = 50, 99.5 % at 60, 97 % of 200 at 70, 81.5 % at 100. No energy
        # shaping: the system's energy counts the arm's spin, which alone carries the upright
        # energy at about 6.5 rad/s with the pendulum hanging, so an energy potential would
        # pay for spinning the arm; the `upright` reward (cos theta) already grows with the
        # pendulum's height. gamma 0.995 looks 4 s ahead, past a 3 s swing-up (the plan's
        # horizon); the rest of the settings are the acrobot's (envs.tasks.swing_up). n_timesteps
        # also sets how often a --budget run evaluates (every 30th: 50k steps). At 500k
        # (every 16.7k) a pendubot run evaluated 100, 75, 90, 50 % at 16.7k-66.7k steps:
        # no two in a row at 80 %.
        "ppo": envs.swing_up_ppo(1_500_000, 0.995, {"level": 50.0, "verify": 3.0}),
        "plan": {"horizon": 3.0},
    },
)
envs.register("Examples/FurutaSwingUp-v0", TASK)
