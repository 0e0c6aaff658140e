"""Training's evaluation, the confirmation and agents.evaluate score a model alike: the
same starts give the same episodes (so a gap between training's "solved" and the check's
fresh evaluation is statistics, not a difference of setup)."""

from __future__ import annotations

import numpy as np
import pytest
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.vec_env import sync_envs_normalization

import envs
from agents import evaluate as programs
from agents.learning import confirm as confirmation
from agents.learning.hparams import load_hyperparams
from agents.learning.vecenv import make_envs
from agents.scoring import fresh
from agents.train import train

BEAD = next(e for e in envs.ENV_IDS if "/BeadOnRod-" in e)


@pytest.mark.slow
def test_training_s_evaluation_the_confirmation_and_the_check_see_the_same_episodes(tmp_path):
    result = train(BEAD, timesteps=512, n_envs=1, eval_episodes=2, progress=False,
                   run_dir=tmp_path, seed=0)  # fmt: skip
    model, hp, n = result.model, load_hyperparams("ppo", BEAD), 5
    # training's evaluation env (VecNormalize frozen, the rewards' wrappers), as make_envs
    # builds it for seed 0: its copies' first episodes start from seeds 10000..10004
    _, eval_env = make_envs(BEAD, hp, 1, 0, "auto", n)
    sync_envs_normalization(model.get_env(), eval_env)
    returns, lengths = evaluate_policy(model, eval_env, n_eval_episodes=n, deterministic=True,
                                       return_episode_rewards=True)  # fmt: skip
    eval_env.close()
    check = programs.evaluate(BEAD, str(result.model_path), n, 10_000)
    # SB3 lists episodes in the order they end; the returns agree to float32's precision
    # (the vector env's observations reach the policy as float32 on one path, float64 cast
    # once on the other: 1e-4 of returns of order 100 is a few float32 ulps per step)
    np.testing.assert_allclose(sorted(returns), sorted(check.returns), rtol=1e-5, atol=1e-3)
    assert sorted(lengths) == sorted(check.lengths.tolist())
    # the confirmation scores the live model as agents.evaluate scores the saved one
    record = fresh.confirm(model, BEAD, hp, attempt=0, episodes=n)
    again = programs.evaluate(BEAD, str(result.model_path), n, confirmation.SEED)
    assert record["successes"] == int(again.successes.sum())
    assert record["seeds"] == [confirmation.SEED, confirmation.SEED + n - 1]
