"""The Furuta pendulum of furuta.py swung up from hanging: the same model and task with the
start at theta = pi +- 0.1, no failure region, and the planner's horizon declared, so
`--agent plan` (trajectory optimisation + TVLQR) can solve it.
`examples.furuta_swing_up:Examples/FurutaSwingUp-v0`."""

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
        # horizon); entropy and a wide initial std keep it swinging until it reaches the set.
        "ppo": {
            "n_timesteps": 1_500_000,
            "n_steps": 512,
            "gamma": 0.995,
            "learning_rate": "lin_3.0e-4",
            "ent_coef": 0.01,
            "normalize": {"norm_obs": True, "norm_reward": True, "gamma": 0.995},
            "policy_kwargs": {"net_arch": [64, 64], "log_std_init": 0.5},
            "handover": {"level": 50.0, "verify": 3.0},
        },
        "plan": {"horizon": 3.0},
    },
)
envs.register("Examples/FurutaSwingUp-v0", TASK)
