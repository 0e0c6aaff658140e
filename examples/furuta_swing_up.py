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
    hyperparams={"plan": {"horizon": 3.0}},
)
envs.register("Examples/FurutaSwingUp-v0", TASK)
