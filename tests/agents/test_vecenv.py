"""The SB3 adapter of Gymnasium vector envs agrees with SB3's own DummyVecEnv."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env import DummyVecEnv

import envs  # noqa: F401  (registers the Lagrange ids)
from agents.learning.vecenv import GymnasiumVecEnv, make_sb3_vec_env, supports_native

ENV_ID = "Lagrange/BeadOnRod-v1"  # zero torque: the bead leaves the rod within ~20 steps


@pytest.mark.parametrize("vectorization", ["sync", "native"])
def test_adapter_steps_like_dummy_vec_env_through_episode_ends(vectorization):
    n = 3
    if vectorization == "sync":
        same_step = gym.make_vec(
            ENV_ID,
            num_envs=n,
            vectorization_mode="sync",
            vector_kwargs={"autoreset_mode": AutoresetMode.SAME_STEP},
        )
    else:  # the runtime's own vector env, one batched step for every copy
        same_step = gym.make_vec(
            ENV_ID, n, vectorization_mode="vector_entry_point", autoreset_mode="SameStep"
        )
    adapted = GymnasiumVecEnv(same_step)
    dummy = DummyVecEnv([lambda: gym.make(ENV_ID) for _ in range(n)])
    adapted.seed(7)
    dummy.seed(7)
    obs_a, obs_d = adapted.reset(), dummy.reset()
    np.testing.assert_array_equal(obs_a, obs_d)
    ends = 0
    for _ in range(60):
        act = np.zeros((n, 1), dtype=np.float32)
        obs_a, rew_a, done_a, info_a = adapted.step(act)
        obs_d, rew_d, done_d, info_d = dummy.step(act)
        # identical physics and seeds: bit-identical observations, rewards and resets
        np.testing.assert_array_equal(obs_a, obs_d)
        np.testing.assert_array_equal(rew_a, rew_d)
        np.testing.assert_array_equal(done_a, done_d)
        for i in np.flatnonzero(done_d):
            ends += 1
            np.testing.assert_array_equal(
                info_a[i]["terminal_observation"], info_d[i]["terminal_observation"]
            )
            assert info_a[i]["TimeLimit.truncated"] == info_d[i]["TimeLimit.truncated"]
            assert info_a[i]["is_success"] == info_d[i]["is_success"]
    assert ends >= n, "no episode ended: the comparison did not cover autoreset"


def test_adapter_refuses_next_step_autoreset():
    venv = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="vector_entry_point")
    assert venv.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP  # Gymnasium's default
    with pytest.raises(ValueError, match="SAME_STEP"):
        GymnasiumVecEnv(venv)
    assert supports_native(ENV_ID)  # asked for, the native env autoresets in the same step


def test_auto_vectorization_gives_sb3_a_working_vec_env():
    venv = make_sb3_vec_env(ENV_ID, 2, seed=0)
    obs = venv.reset()
    assert obs.shape == (2,) + venv.observation_space.shape
    with pytest.raises(ValueError, match="vectorization must be one of"):
        make_sb3_vec_env(ENV_ID, 2, seed=0, vectorization="threads")
