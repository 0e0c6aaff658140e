"""The swing-up examples' declared LQR hand-over (agents.control.handover): LQR captures
from the level set their tasks declare, as tests/agents/test_handover.py checks for
Lagrange/Acrobot-v2."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from agents.control.handover import CaptureSet
from agents.learning import hparams
from examples import furuta_swing_up, pendubot  # noqa: F401 (they register the ids)

SWING_UPS = ("Examples/Pendubot-v0", "Examples/FurutaSwingUp-v0")


@pytest.mark.parametrize("env_id", SWING_UPS)
def test_lqr_captures_from_the_declared_level_set(env_id):
    handover = hparams.load("ppo", env_id)["handover"]
    directions = 40
    vec = gym.make_vec(env_id, num_envs=directions, vectorization_mode="vector_entry_point")
    try:
        vec.reset(seed=0)
        capture = CaptureSet(vec, handover["level"], verify=handover["verify"])
        x0, u0 = vec.unwrapped.operating_point()
        P = capture.lqr.design(x0[0], u0[0]).P
        z = np.random.default_rng(0).normal(size=(directions, P.shape[0]))
        dx = np.linalg.solve(np.linalg.cholesky(P).T, z.T).T
        dx *= np.sqrt(capture.level / np.einsum("bi,ij,bj->b", dx, P, dx))[:, None]
        obs, _ = vec.reset(seed=0, options={"state": x0 + dx, "goal": vec.unwrapped.goal})
        ended = np.zeros(directions, dtype=bool)
        for _ in range(capture.verify_steps):  # the declared check's horizon (3 s)
            obs, _, terminated, _, info = vec.step(capture.lqr.predict(obs)[0])
            ended |= terminated
    finally:
        vec.close()
    # measured (10 s of LQR, the tasks' comments): 99.6 % of 1000 directions at the
    # pendubot's level, 100 % at the Furuta's; LQR reaches success within 0.8 s (pendubot)
    # and 2 s (Furuta) from these directions, so 3 s sees every capture. At twice either
    # level LQR captures 67.5 % and 70 % of these 40 directions: the bound tells them apart.
    assert capture.verify_steps * vec.unwrapped.control_period >= 2.0
    assert (info["is_success"] & ~ended).mean() >= 0.95
