"""Training end to end on every environment, save/load, resume and the command line."""

from __future__ import annotations

import numpy as np
import pytest

import envs
from agents.common import UserError
from agents.learning.rundir import latest_checkpoint
from agents.scoring.trained import SB3Policy
from agents.train import main, train


def _env_id(name: str) -> str:
    """The registered id of a Lagrange env by name, whatever its version."""
    return next(env_id for env_id in envs.ENV_IDS if f"/{name}-" in env_id)


ARM, BEAD, CRANK = _env_id("TwoLinkArm"), _env_id("BeadOnRod"), _env_id("CrankSlider")

# PPO with one env collects rollouts of n_steps = 256 or 512 steps (ppo.yml): 512 steps are
# whole rollouts on every env.
SMALL = dict(algo="ppo", n_envs=1, eval_freq=512, eval_episodes=2, progress=False)


@pytest.mark.parametrize(
    "env_id",
    # one env in the fast suite; every env with -m slow (each builds its own networks)
    [e if "BeadOnRod" in e else pytest.param(e, marks=pytest.mark.slow) for e in envs.ENV_IDS],
)
def test_a_few_hundred_steps_train_end_to_end(env_id, tmp_path):
    result = train(env_id, timesteps=512, run_dir=tmp_path, **SMALL)
    assert result.timesteps == 512
    for name in (
        "config.yml",
        "model.zip",
        "vecnormalize.pkl",
        "episodes.csv",
        "eval.csv",
        "learning_curve.png",
    ):
        assert (tmp_path / name).stat().st_size > 0, name
    assert latest_checkpoint(tmp_path / "checkpoints")[0] == 512
    rows = (tmp_path / "eval.csv").read_text().splitlines()
    assert rows[0].startswith("timesteps,mean_return") and rows[1].startswith("512,")
    assert not list(tmp_path.glob(".*.zip")), "a temporary file was left behind"


@pytest.mark.slow
def test_saved_model_gives_identical_actions(tmp_path):
    result = train(ARM, timesteps=512, run_dir=tmp_path, **SMALL)
    vecnorm = result.model.get_vec_normalize_env()
    shape = (32,) + vecnorm.observation_space.shape
    obs = np.random.default_rng(0).uniform(-1, 1, shape).astype(np.float32)
    expected, _ = result.model.predict(vecnorm.normalize_obs(obs), deterministic=True)
    loaded = SB3Policy.load(tmp_path)
    actions, _ = loaded.predict(obs, deterministic=True)
    np.testing.assert_array_equal(actions, expected)  # same weights, same float32 arithmetic


@pytest.mark.slow
def test_resume_continues_the_timestep_count_and_the_learning_rate_schedule(tmp_path):
    # A run stopped at its 512-step checkpoint, then resumed to a budget of 1024.
    train(BEAD, timesteps=512, run_dir=tmp_path, **SMALL)
    first = (tmp_path / "eval.csv").read_text().splitlines()
    result = train(BEAD, timesteps=1024, run_dir=tmp_path, resume=True, **SMALL)
    model = result.model
    assert model.num_timesteps == 1024
    assert model._total_timesteps == 1024  # a restarted schedule would count 512 here
    # the linear schedule is evaluated on the progress of the whole run, not of the resume
    progress = 1.0 - model.num_timesteps / model._total_timesteps
    assert model._current_progress_remaining == pytest.approx(progress)
    lr = model.policy.optimizer.param_groups[0]["lr"]
    assert lr == pytest.approx(model.lr_schedule(progress))
    # the learning curve keeps the rows of the first part and continues after them
    rows = (tmp_path / "eval.csv").read_text().splitlines()
    assert rows[: len(first)] == first and rows[-1].startswith("1024,")


@pytest.mark.slow
def test_resume_without_a_checkpoint_starts_fresh(tmp_path, capsys):
    result = train(BEAD, timesteps=512, run_dir=tmp_path, resume=True, **SMALL)
    assert result.timesteps == 512
    assert "starting a fresh run" in capsys.readouterr().err


def test_hyperparameters_exist_for_every_env_and_algorithm():
    from agents.learning import hparams

    for algo in hparams.ALGOS:
        for env_id in envs.ENV_IDS:
            kwargs = hparams.algo_kwargs(algo, hparams.load(algo, env_id), 2)
            assert "policy_kwargs" in kwargs


@pytest.mark.parametrize(
    "argv, message",
    [
        ([ARM[:-1] + "9"], f"Did you mean {ARM!r}"),
        (["TwoLinkArm"], f"Did you mean {ARM!r}"),
        ([BEAD, "--algo", "dqn"], "unknown algorithm 'dqn'"),
        ([BEAD, "--timesteps", "-5"], "expected a positive integer, got -5"),
        ([BEAD, "--timesteps", "lots"], "expected a positive integer"),
        ([BEAD, "--n-envs", "0"], "expected a positive integer, got 0"),
        ([BEAD, "--seed", "-1"], "expected an integer >= 0, got -1"),
    ],
)
def test_cli_rejects_bad_arguments_with_clear_messages(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    assert message in capsys.readouterr().err


@pytest.mark.slow
def test_cli_trains_and_reports(tmp_path, capsys):
    code = main(
        [
            BEAD,
            "--timesteps",
            "512",
            "--n-envs",
            "1",
            "--eval-freq",
            "512",
            "--eval-episodes",
            "1",
            "--run-dir",
            str(tmp_path),
            "--no-progress",
        ]
    )
    assert code == 0
    out = capsys.readouterr().out
    assert f"ppo on {BEAD}: 512 steps" in out and "model.zip" in out


@pytest.mark.slow  # two trainings each
@pytest.mark.parametrize("algo", ["sac", "td3"])
def test_off_policy_algorithms_train_and_resume_with_their_replay_buffer(algo, tmp_path):
    kwargs = dict(algo=algo, eval_freq=300, eval_episodes=1, progress=False, run_dir=tmp_path)
    train(CRANK, timesteps=300, **kwargs)
    steps, _ = latest_checkpoint(tmp_path / "checkpoints")
    assert steps == 300
    assert (tmp_path / "checkpoints" / f"rl_model_replay_buffer_{steps}_steps.pkl").exists()
    result = train(CRANK, timesteps=400, resume=True, **kwargs)
    assert result.model.num_timesteps == 400
    assert result.model.replay_buffer.size() == 400  # the buffer came back with the model


@pytest.mark.slow  # three trainings
def test_an_earlier_run_is_replaced_only_when_asked(tmp_path):
    train(CRANK, timesteps=1024, run_dir=tmp_path, **SMALL)
    with pytest.raises(UserError) as refused:
        train(CRANK, timesteps=512, run_dir=tmp_path, **SMALL)
    message = str(refused.value)
    assert str(tmp_path) in message and "--resume" in message and "--overwrite" in message
    assert latest_checkpoint(tmp_path / "checkpoints")[0] == 1024  # nothing was touched
    train(CRANK, timesteps=512, run_dir=tmp_path, overwrite=True, **SMALL)
    names = sorted(p.name for p in (tmp_path / "checkpoints").iterdir())
    assert names == ["rl_model_512_steps.zip", "rl_model_vecnormalize_512_steps.pkl"]
    assert [r.split(",")[0] for r in (tmp_path / "eval.csv").read_text().splitlines()] == [
        "timesteps",
        "512",
    ]
