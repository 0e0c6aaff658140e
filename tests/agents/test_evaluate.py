"""Evaluation: episode accounting against a single env, videos, and bad arguments."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from agents.evaluate import evaluate, main, make_agent


def test_batched_evaluation_counts_each_episode_like_a_single_env():
    env_id, seed = "Lagrange/BeadOnRod-v1", 3
    stats = evaluate(env_id, "lqr", episodes=3, seed=seed)
    env = gym.make(env_id)
    policy = make_agent("lqr", env)
    for i in range(3):
        obs, _ = env.reset(seed=seed + i)  # copy i of the vector env is seeded seed + i
        total, steps, done = 0.0, 0, False
        while not done:
            obs, r, terminated, truncated, info = env.step(policy.predict(obs)[0])
            total, steps, done = total + r, steps + 1, terminated or truncated
        # the same float32 observations and float64 dynamics: equal to summation rounding
        assert stats.returns[i] == pytest.approx(total, rel=1e-9, abs=1e-9)
        assert stats.lengths[i] == steps
        assert stats.successes[i] == info["is_success"]


def test_bead_leaving_the_rod_ends_zero_torque_episodes_early():
    stats = evaluate("Lagrange/BeadOnRod-v1", "zero", episodes=5)
    assert stats.mean_length < 200 and stats.success_rate == 0.0
    assert np.isfinite(stats.returns).all()


@pytest.mark.slow  # encodes an mp4
def test_video_of_the_first_episode(tmp_path):
    pytest.importorskip("moviepy")
    evaluate("Lagrange/CrankSlider-v1", "heuristic", episodes=1, video_dir=tmp_path / "videos")
    videos = list((tmp_path / "videos").glob("*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 1000


@pytest.mark.parametrize(
    "argv, message",
    [
        (["Lagrange/Acrobat-v1", "--agent", "zero"], "Did you mean 'Lagrange/Acrobot-v1'"),
        (["Lagrange/Acrobot-v1", "--agent", "pid"], "unknown agent 'pid'"),
        (["Lagrange/Acrobot-v1", "--agent", "zero", "--episodes", "0"], "got 0"),
        (["Lagrange/Acrobot-v1"], "--agent"),
    ],
)
def test_cli_rejects_bad_arguments(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2 and message in capsys.readouterr().err


def test_cli_prints_the_scores(capsys):
    assert main(["Lagrange/CrankSlider-v1", "--agent", "lqr", "--episodes", "2"]) == 0
    assert "lqr on Lagrange/CrankSlider-v1: return" in capsys.readouterr().out


def test_evaluate_rejects_a_non_positive_episode_count():
    with pytest.raises(ValueError, match="episodes must be a positive integer"):
        evaluate("Lagrange/CrankSlider-v1", "zero", episodes=0)
