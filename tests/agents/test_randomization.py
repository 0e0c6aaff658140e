"""Training with randomised physical parameters: the setting's forms, its errors, the
training envs drawing their parameters, and the run directory keeping the setting."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from agents.common import UserError
from agents.learning.hparams import load_hyperparams
from agents.learning.randomization import env_kwargs, parse_option, ranges, scaled
from agents.learning.vecenv import make_envs
from agents.train import main, train

ARM, BEAD = "Lagrange/TwoLinkArm-v1", "Lagrange/BeadOnRod-v1"
SMALL = dict(algo="ppo", n_envs=1, eval_freq=512, eval_episodes=2, progress=False)


def _system(env_id):
    import gymnasium as gym

    return gym.make(env_id).unwrapped.system


def test_inertial_means_every_mass_and_inertia_scaled_from_the_nominal():
    got = ranges(_system(ARM), {"inertial": 0.25, "m2": [0.9, 1.0]})
    assert set(got) == {"m1", "m2", "Ibar1", "Ibar2"}  # lengths (m) and g are left out
    assert got["m1"] == (0.75, 1.25)
    assert got["Ibar1"] == pytest.approx((0.75 / 12, 1.25 / 12))
    assert got["m2"] == (0.9, 1.0)  # a named entry overrides the group
    # a negative nominal (a product of inertia, as the bicycle's I_Hxz) keeps low <= high
    assert scaled(-0.00756, 0.1) == pytest.approx((-0.008316, -0.006804))


def test_the_command_line_form_and_its_errors():
    assert parse_option(["inertial=0.25", "m2=0.8:1.2"]) == {"inertial": 0.25, "m2": [0.8, 1.2]}
    assert parse_option(None) is None
    for bad in (["inertial"], ["inertial=1.5"], ["m2=1.2:0.8"], ["m2=a"], ["m2=1", "m2=2"]):
        with pytest.raises(UserError, match="--randomize"):
            parse_option(bad)
    with pytest.raises(UserError, match="unknown parameter 'mass' of two_link_arm.*m1"):
        ranges(_system(ARM), {"mass": 0.1})
    with pytest.raises(UserError, match="must be positive"):  # the env's own check
        env_kwargs(ARM, {"m1": [-1.0, 1.0]})


def test_the_training_envs_draw_their_parameters_at_every_reset():
    hp = {**load_hyperparams("ppo", ARM), "randomize": {"inertial": 0.25}}
    train_env, eval_env = make_envs(ARM, hp, 4, 0, "native", 2)
    try:
        for venv in (train_env, eval_env):
            venv.reset()
            inner = venv
            while not any("params" in i for i in inner.reset_infos):  # the vec env under
                inner = inner.venv  # VecNormalize and the training's reward wrappers
            m1 = np.array([info["params"]["m1"] for info in inner.reset_infos])
            assert ((0.75 <= m1) & (m1 <= 1.25)).all()
            assert len(set(m1.tolist())) == len(m1)  # each copy its own draw
    finally:
        train_env.close()
        eval_env.close()


@pytest.mark.slow
def test_the_setting_is_saved_and_a_resume_keeps_it(tmp_path):
    train(BEAD, timesteps=512, run_dir=tmp_path, randomize={"m": 0.2}, **SMALL)
    config = yaml.safe_load((tmp_path / "config.yml").read_text())
    assert config["hyperparams"]["randomize"] == {"m": 0.2}
    assert config["env_options"]["randomize"]["m"] == pytest.approx([0.08, 0.12])
    # resumed (finished: nothing more to learn) without the setting: the run's is kept
    train(BEAD, timesteps=512, run_dir=tmp_path, resume=True, **SMALL)
    config = yaml.safe_load((tmp_path / "config.yml").read_text())
    assert config["hyperparams"]["randomize"] == {"m": 0.2}
    assert config["env_options"]["randomize"]["m"] == pytest.approx([0.08, 0.12])


def test_the_yaml_hyperparameter_is_checked(tmp_path):
    path = tmp_path / "hp.yml"
    path.write_text(f"{BEAD}:\n  randomize: {{inertial: 2}}\n")
    with pytest.raises(UserError, match=r"randomize must be inertial to be a fraction"):
        load_hyperparams("ppo", BEAD, path)
    path.write_text(f"{BEAD}:\n  randomize: {{inertial: 0.1}}\n")
    assert load_hyperparams("ppo", BEAD, path)["randomize"] == {"inertial": 0.1}


def test_the_command_line_refuses_a_bad_setting_before_writing(tmp_path, capsys):
    run = tmp_path / "run"
    assert main([BEAD, "--randomize", "nope=0.1", "--run-dir", str(run)]) == 2
    assert "unknown parameter 'nope'" in capsys.readouterr().err
    assert not (run / "config.yml").exists()


@pytest.mark.slow  # trains, and runs every baseline
def test_check_trains_a_randomised_run_in_a_directory_of_its_own(tmp_path):
    from agents.check import run_check

    tiny = tmp_path / "tiny.yml"
    tiny.write_text(yaml.safe_dump({ARM: {"n_envs": 1, "n_steps": 64, "batch_size": 64}}))
    rows = run_check(
        [ARM], episodes=2, out=tmp_path, timesteps=128, progress=False, hyperparams=tiny,
        randomize={"inertial": 0.25},
    )  # fmt: skip
    run = (
        tmp_path / "train" / "Lagrange-TwoLinkArm-v1" / "ppo_seed0_128steps_randomized-inertial0.25"
    )
    config = yaml.safe_load((run / "config.yml").read_text())
    assert config["hyperparams"]["randomize"] == {"inertial": 0.25}
    assert rows[-1].note == "randomised: every mass and inertia over [0.75, 1.25] x nominal"


def test_check_refuses_a_bad_setting(capsys):
    from agents.check import main as check_main

    with pytest.raises(SystemExit) as exc:
        check_main([ARM, "--randomize", "inertial=2"])
    assert (
        exc.value.code == 2 and "--randomize: inertial to be a fraction" in capsys.readouterr().err
    )


def test_evaluate_draws_each_episode_s_parameters(capsys):
    from agents.evaluate import evaluate
    from agents.evaluate import main as evaluate_main

    nominal = evaluate(ARM, "lqr", 4, seed=3)
    drawn = evaluate(ARM, "lqr", 4, seed=3, randomize={"m2": [1.5, 2.0]})
    assert not np.array_equal(nominal.returns, drawn.returns)  # same starts, other plants
    argv = [ARM, "--agent", "zero", "--episodes", "2", "--randomize", "inertial=0.25"]
    assert evaluate_main(argv) == 0
    out = capsys.readouterr().out
    assert "(randomised: every mass and inertia over [0.75, 1.25] x nominal)" in out
