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


@pytest.mark.slow
def test_cli_prints_the_scores(capsys):
    assert main(["Lagrange/CrankSlider-v1", "--agent", "lqr", "--episodes", "2"]) == 0
    assert "lqr on Lagrange/CrankSlider-v1: return" in capsys.readouterr().out


def test_evaluate_rejects_a_non_positive_episode_count():
    with pytest.raises(ValueError, match="episodes must be a positive integer"):
        evaluate("Lagrange/CrankSlider-v1", "zero", episodes=0)


# ---- saved runs are checked against the env they are loaded for (issue 20) ---------------
@pytest.fixture(scope="module")
def bead_run(tmp_path_factory):
    from agents.train import train

    run = tmp_path_factory.mktemp("bead_run")
    train("Lagrange/BeadOnRod-v1", timesteps=256, n_envs=1, run_dir=run, progress=False)
    return run


def _foreign_vecnormalize(path):
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    VecNormalize(DummyVecEnv([lambda: gym.make("Lagrange/TwoLinkArm-v1")])).save(path)


@pytest.mark.parametrize(
    "damage, env_id, message",
    [
        (None, "Lagrange/CrankSlider-v1", "trained on Lagrange/BeadOnRod-v1, not on"),
        (None, "Lagrange/Acrobot-v2", "trained on Lagrange/BeadOnRod-v1, not on"),
        ("foreign statistics", None, "normalises observations of shape (14,)"),
        ("truncated statistics", None, "vecnormalize.pkl cannot be read"),
        ("truncated model", None, "is not a PPO, SAC or TD3 model"),
        ("config a list", None, "config.yml is not a run's config"),
        ("config without env_id", None, "env_id must be a string"),
    ],
)
def test_a_saved_run_is_checked_against_the_env_in_one_line(
    bead_run, tmp_path, damage, env_id, message, capsys
):
    import shutil

    run = tmp_path / "run"
    shutil.copytree(bead_run, run)
    if damage == "foreign statistics":
        _foreign_vecnormalize(run / "vecnormalize.pkl")
    elif damage is not None and damage.startswith("truncated"):
        f = run / ("model.zip" if damage.endswith("model") else "vecnormalize.pkl")
        f.write_bytes(f.read_bytes()[:100])
    elif damage == "config a list":
        (run / "config.yml").write_text("- env_id\n- algo\n")
    elif damage == "config without env_id":
        (run / "config.yml").write_text("algo: ppo\n")
    argv = [env_id or "Lagrange/BeadOnRod-v1", "--agent", str(run), "--episodes", "2"]
    with pytest.raises(SystemExit) as ended:
        main(argv)
    err = capsys.readouterr().err.strip()
    assert ended.value.code == 2
    assert message in err and len(err.splitlines()) == 1 and "Traceback" not in err, err


def test_a_saved_run_evaluates_on_its_own_env(bead_run):
    stats = evaluate("Lagrange/BeadOnRod-v1", str(bead_run), episodes=2)
    assert len(stats.returns) == 2
