"""Every command on a system the project has never seen (examples/), by Gymnasium's
module:Env-v0 form, and a clear line for envs that are not built on the runtime."""

from __future__ import annotations

import pytest

from agents import check, evaluate, lqr
from agents.learning import declared, hparams
from examples import cart_pole  # noqa: F401  (registers it)

USER_ID = "examples.cart_pole:Examples/CartPole-v0"


def test_lqr_command_on_a_user_system(capsys):
    assert lqr.main([USER_ID, "--episodes", "20"]) == 0
    out = capsys.readouterr().out
    assert "LQR: success 20/20" in out


def test_evaluate_command_on_a_user_system(capsys):
    assert evaluate.main([USER_ID, "--agent", "lqr", "--episodes", "5"]) == 0
    assert "success 100%" in capsys.readouterr().out


def test_a_missing_heuristic_is_one_clear_line(capsys):
    with pytest.raises(SystemExit) as exc:
        evaluate.main([USER_ID, "--agent", "heuristic", "--episodes", "2"])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "declares no heuristic" in err[0]


@pytest.mark.parametrize("main", [lqr.main, check.main])
def test_an_env_not_built_on_the_runtime_gets_a_clear_error(main, capsys):
    with pytest.raises(SystemExit):
        main(["Acrobot-v1"])
    assert "not built on the Lagrange runtime" in capsys.readouterr().err


def test_a_user_system_gets_default_hyperparameters():
    hp = hparams.load("ppo", "Examples/CartPole-v0")
    assert hp["n_timesteps"] == 100_000 and hp["normalize"] is True
    assert hparams.check_algo("Examples/CartPole-v0") == "ppo"


def test_every_agent_trains_until_solved_within_ten_minutes_and_its_declared_steps(tmp_path):
    user = "Examples/CartPole-v0"  # registered by importing examples.cart_pole
    assert declared.seconds_of(None, None) == 600.0  # the command names no budget
    assert declared.seconds_of(5000, None) is None  # --timesteps: the steps, to the end
    assert declared.seconds_of(None, 90.0) == 90.0  # --budget
    assert declared.steps_cap(user, None, None, None, None) is None  # nothing declared
    # a built-in task declares its steps, a cap on the ten minutes; so may a file, for any env
    assert declared.steps_cap("Lagrange/BeadOnRod-v1", None, None, None, None) == 200_000
    assert declared.steps_cap("Lagrange/BeadOnRod-v1", None, None, 90.0, None) is None
    own = tmp_path / "ppo.yml"
    own.write_text(f"{user}:\n  n_timesteps: 20000\n")
    assert declared.steps_cap(user, "ppo", None, None, own) == 20_000
    own.write_text("default:\n  learning_rate: 0.0003\n")  # other settings: no cap
    assert declared.steps_cap(user, "ppo", None, None, own) is None


@pytest.mark.slow
def test_the_plain_command_on_a_user_system_trains_until_solved(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(declared, "DEFAULT_SECONDS", 20.0)  # 10 minutes, shortened
    argv = [USER_ID, "--episodes", "4", "--out", str(tmp_path), "--no-progress"]
    assert check.main(argv) == 0
    report = (tmp_path / "Examples-CartPole-v0" / "results.md").read_text()
    row = next(
        line for line in report.splitlines() if line.startswith("| Examples/CartPole-v0 | ppo |")
    )
    assert "solved after" in row or "not solved in 20 s" in row


@pytest.mark.slow
def test_main_job_on_a_user_system_end_to_end(tmp_path, capsys):
    argv = [USER_ID, "--timesteps", "1024", "--episodes", "4", "--out", str(tmp_path)]
    assert check.main(argv + ["--no-progress"]) == 0
    # its own report, named by the budget asked for
    report = (tmp_path / "Examples-CartPole-v0_1024steps" / "results.md").read_text()
    for agent in ("random", "zero", "lqr", "ppo"):
        assert f"| Examples/CartPole-v0 | {agent} |" in report


@pytest.mark.slow
def test_train_command_on_a_user_system(tmp_path, capsys):
    from agents import train

    argv = [USER_ID, "--timesteps", "512", "--run-dir", str(tmp_path), "--no-progress"]
    assert train.main(argv) == 0
    assert (tmp_path / "model.zip").is_file()
    assert "Examples/CartPole-v0" in capsys.readouterr().out


def test_a_model_trained_on_another_env_is_one_clear_line(tmp_path, capsys):
    import gymnasium as gym
    from stable_baselines3 import PPO

    PPO("MlpPolicy", gym.make("Lagrange/BeadOnRod-v1"), device="cpu").save(tmp_path / "model")
    with pytest.raises(SystemExit) as exc:
        evaluate.main(["Lagrange/TwoLinkArm-v1", "--agent", str(tmp_path / "model.zip")])
    err = capsys.readouterr().err.strip().splitlines()
    assert exc.value.code == 2 and len(err) == 1
    assert "trained on another environment" in err[0]


def test_a_file_that_is_no_model_is_one_clear_line(tmp_path, capsys):
    notes = tmp_path / "notes.txt"
    notes.write_text("not a model")
    with pytest.raises(SystemExit):
        evaluate.main(["Lagrange/BeadOnRod-v1", "--agent", str(notes)])
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is not a PPO, SAC or TD3 model" in err[0]
