"""Observation statistics about zero (agents.learning.uncentered): what they hold, that a
training run keeps them by default and SB3's centred ones on request, and the premise
that makes the difference (an SB3 policy starts odd about the normalised zero)."""

from __future__ import annotations

import numpy as np
import pytest
from stable_baselines3.common.running_mean_std import RunningMeanStd

from agents.common import UserError
from agents.learning import hparams
from agents.learning.uncentered import UncenteredMeanStd
from agents.learning.vecenv import make_envs

BEAD = "Lagrange/BeadOnRod-v1"


def test_the_statistics_are_the_running_mean_of_the_squares_about_zero():
    rng = np.random.default_rng(0)
    batches = [rng.normal([3.0, -1.0, 0.0], [0.5, 2.0, 1.0], (n, 3)) for n in (7, 100, 1000)]
    rms = UncenteredMeanStd(shape=(3,))
    for b in batches:
        rms.update(b)
    data = np.concatenate(batches)
    np.testing.assert_array_equal(rms.mean, 0.0)
    # the prior (var 1 at count 1e-4) weighs 1e-4 / 1107 of the result: relative 1e-6
    np.testing.assert_allclose(rms.var, np.mean(data**2, axis=0), rtol=1e-6)
    copy = rms.copy()
    assert isinstance(copy, UncenteredMeanStd) and copy.count == rms.count
    np.testing.assert_array_equal(copy.var, rms.var)
    centred = RunningMeanStd(shape=(3,))  # SB3's statistics of the same data, combined in
    centred.update(data)
    copy.combine(centred)
    np.testing.assert_allclose(copy.var, np.mean(data**2, axis=0), rtol=1e-6)


def _envs(normalize):
    hp = {**hparams.load_hyperparams("ppo", BEAD), "normalize": normalize}
    return make_envs(BEAD, hp, n_envs=2, seed=0, vectorization="auto", eval_envs=2)


def test_a_training_run_scales_observations_about_zero_unless_it_asks_to_centre():
    train_env, eval_env = _envs(True)
    try:
        assert type(train_env.obs_rms) is UncenteredMeanStd
        assert type(eval_env.obs_rms) is UncenteredMeanStd
        raw = []
        train_env.reset()
        for _ in range(20):
            train_env.step(np.zeros((2, 1), np.float32))
            raw.append(train_env.get_original_obs())
        assert np.all(train_env.obs_rms.mean == 0.0) and np.all(train_env.obs_rms.var != 1.0)
        obs = raw[-1]
        expected = np.clip(obs / np.sqrt(train_env.obs_rms.var + train_env.epsilon), -10.0, 10.0)
        np.testing.assert_allclose(train_env.normalize_obs(obs), expected, rtol=1e-6)
    finally:
        train_env.close()
        eval_env.close()
    train_env, eval_env = _envs({"center": True, "norm_reward": False})
    try:
        assert type(train_env.obs_rms) is RunningMeanStd and not train_env.norm_reward
    finally:
        train_env.close()
        eval_env.close()


@pytest.mark.parametrize("value", [3, "no", None])
def test_center_is_true_or_false(value):
    with pytest.raises(UserError, match="center"):
        hparams.check_entries({"normalize": {"center": value}}, "my.yml (default)")


def test_an_sb3_policy_starts_odd_about_the_normalised_zero():
    # the premise of scaling about zero: a fresh policy's action is zero where the
    # normalised observation is, so centring would put its first fixed point at the mean
    import torch
    from stable_baselines3 import PPO

    train_env, eval_env = _envs(True)
    try:
        policy = PPO("MlpPolicy", train_env, seed=0, device="cpu").policy
        size = (16, train_env.observation_space.shape[0])
        x = torch.as_tensor(np.random.default_rng(1).normal(size=size), dtype=torch.float32)
        with torch.no_grad():
            mean = lambda o: policy.get_distribution(o).distribution.mean  # noqa: E731
            zero = mean(torch.zeros_like(x[:1]))
            np.testing.assert_array_equal(zero.numpy(), 0.0)
            np.testing.assert_allclose(mean(-x).numpy(), -mean(x).numpy(), atol=1e-7)
    finally:
        train_env.close()
        eval_env.close()
