"""The training command's run-directory rules, hyperparameter file and one-line errors."""

from __future__ import annotations

import pytest
import yaml

import envs
from agents.common import UserError
from agents.train import exclusive, main, train

BEAD = next(env_id for env_id in envs.ENV_IDS if "/BeadOnRod-" in env_id)


def _one_line_error(argv, capsys) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert err.startswith("python -m agents.train: error: ")
    return err


def test_a_directory_with_an_earlier_run_is_not_trained_into_unasked(tmp_path, capsys):
    (tmp_path / "model.zip").write_bytes(b"an earlier run's model")
    err = _one_line_error([BEAD, "--run-dir", str(tmp_path), "--no-progress"], capsys)
    assert str(tmp_path) in err and "--resume" in err and "--overwrite" in err
    err = _one_line_error([BEAD, "--run-dir", str(tmp_path), "--resume"], capsys)
    assert "no checkpoint" in err and "--overwrite" in err
    err = _one_line_error([BEAD, "--run-dir", str(tmp_path), "--resume", "--overwrite"], capsys)
    assert "not both" in err
    assert (tmp_path / "model.zip").read_bytes() == b"an earlier run's model"


def test_one_process_trains_into_a_directory_at_a_time(tmp_path):
    with exclusive(tmp_path):
        with pytest.raises(UserError, match="Another process is training into"):
            train(BEAD, timesteps=256, run_dir=tmp_path, progress=False)


@pytest.mark.parametrize(
    "text, message",
    [
        (None, "does not exist"),
        ("{BEAD}: {{n_stepz: 64}}", "n_stepz"),
        ("{BEAD}: [1, 2", "YAML"),
        # every value is checked where it is read; the message names the file and the key
        ("{BEAD}: {{n_timesteps: abc}}", "n_timesteps must be an integer in [1, "),
        ("{BEAD}: {{n_envs: two}}", "n_envs must be an integer"),
        ("{BEAD}: {{gamma: 2.0}}", "gamma must be a number in (0.0, 1.0]"),
        ("{BEAD}: {{policy_kwargs: {{net_arch: big}}}}", "net_arch to be a list of 1 to 16"),
        ("{BEAD}: {{learning_rate: lin_fast}}", "learning_rate must be 'lin_X' with X"),
        ("{BEAD}: {{handover: {{level: 5, verify: 1.0e+9}}}}", "verify in [0, 60] seconds"),
        ("{BEAD}: {{normalize: {{clip_obs: -1}}}}", "clip_obs to be a number"),
    ],
)
def test_bad_hyperparameter_files_are_one_line_errors(text, message, tmp_path, capsys):
    path = tmp_path / "hp.yml"
    if text is not None:
        path.write_text(text.format(BEAD=BEAD))
    argv = [BEAD, "--hyperparams", str(path), "--run-dir", str(tmp_path / "run")]
    err = _one_line_error(argv, capsys)
    assert message in err
    assert text is None or str(path) in err
    assert not (tmp_path / "run" / "config.yml").exists()


def test_an_alias_bomb_is_refused_before_it_expands(tmp_path, capsys):
    """Nine levels of ten aliases each stand for 10**9 values in 1 KB; the file is refused
    by counting the shared nodes, never building or printing the expanded value."""
    lines = ["a0: &a0 [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]"]
    for i in range(1, 10):
        lines.append(f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]")
    lines.append(f"{BEAD}: {{handover: *a9}}")
    path = tmp_path / "hp.yml"
    path.write_text("\n".join(lines) + "\n")
    argv = [BEAD, "--hyperparams", str(path), "--run-dir", str(tmp_path / "run")]
    err = _one_line_error(argv, capsys)
    assert "expands to more than" in err and len(err) < 300


@pytest.mark.slow
def test_a_hyperparameter_file_overrides_the_packaged_one(tmp_path):
    path = tmp_path / "hp.yml"
    path.write_text(yaml.safe_dump({BEAD: {"n_steps": 128, "batch_size": 64, "gamma": 0.9}}))
    run = tmp_path / "run"
    result = train(BEAD, "ppo", 128, n_envs=1, run_dir=run, progress=False, hyperparams=path)
    assert result.model.n_steps == 128 and result.model.gamma == 0.9
    config = yaml.safe_load((run / "config.yml").read_text())
    assert config["hyperparams_file"] == str(path) and config["hyperparams"]["n_steps"] == 128


@pytest.mark.slow
def test_progress_shows_in_logs_as_periodic_lines(tmp_path, capsys, monkeypatch):
    """Where stderr is not a terminal (a log file: here, pytest's capture), training prints
    a line every LogProgress.every seconds instead of a progress bar."""
    from agents.learning.callbacks import LogProgress

    monkeypatch.setattr(LogProgress, "every", 0.0)
    train(BEAD, "ppo", 512, n_envs=1, run_dir=tmp_path, progress=True)
    lines = [line for line in capsys.readouterr().err.splitlines() if "steps/s" in line]
    assert len(lines) >= 2 and "PPO on Lagrange/BeadOnRod-v1: 512/512 steps (100%)" in lines[-1]


def test_a_budget_run_s_progress_counts_towards_its_time_not_its_step_cap():
    """A budget run's step count is a cap (agents.learning.budget.BUDGET_STEPS_CAP) that the
    time ends first: its line gives the steps trained and the budget's time left; a run
    that its steps end first still counts towards them."""
    import io
    import time

    from agents.learning.budget import BUDGET_STEPS_CAP
    from agents.learning.callbacks import LogProgress

    def line(total, done, seconds_left):
        stream = io.StringIO()
        log = LogProgress("PPO on X", stream, time_left=lambda: seconds_left)
        log._total, log._first, log._start = total, 0, time.monotonic() - 10.0
        log.num_timesteps = done  # 1,000 steps/s over the 10 s
        log._line()
        return stream.getvalue()

    assert line(BUDGET_STEPS_CAP, 10_000, 90.0).strip() == (
        "PPO on X: 10,000 steps, 1,000 steps/s, about 1.5 min left"
    )
    assert line(40_000, 10_000, 90.0).strip() == (
        "PPO on X: 10,000/40,000 steps (25%), 1,000 steps/s, about 0.5 min left"
    )
