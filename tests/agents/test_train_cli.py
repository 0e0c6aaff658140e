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
    ],
)
def test_bad_hyperparameter_files_are_one_line_errors(text, message, tmp_path, capsys):
    path = tmp_path / "hp.yml"
    if text is not None:
        path.write_text(text.format(BEAD=BEAD))
    argv = [BEAD, "--hyperparams", str(path), "--run-dir", str(tmp_path / "run")]
    assert message in _one_line_error(argv, capsys)
    assert not (tmp_path / "run" / "config.yml").exists()


def test_a_hyperparameter_file_overrides_the_packaged_one(tmp_path):
    path = tmp_path / "hp.yml"
    path.write_text(yaml.safe_dump({BEAD: {"n_steps": 128, "batch_size": 64, "gamma": 0.9}}))
    run = tmp_path / "run"
    result = train(BEAD, "ppo", 128, n_envs=1, run_dir=run, progress=False, hyperparams=path)
    assert result.model.n_steps == 128 and result.model.gamma == 0.9
    config = yaml.safe_load((run / "config.yml").read_text())
    assert config["hyperparams_file"] == str(path) and config["hyperparams"]["n_steps"] == 128
