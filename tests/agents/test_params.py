"""`--params FILE.yml`: identified (or any) model parameters taken by the agents' commands,
checked before work starts, applied to every env a command makes, recorded with a run."""

from __future__ import annotations

import gymnasium as gym
import pytest
import yaml

from agents import check, evaluate, lqr, params, train
from agents.common import UserError, spec

ARM = "Lagrange/TwoLinkArm-v1"
COMMANDS = {"lqr": lqr.main, "evaluate": evaluate.main, "train": train.main, "check": check.main}


def m2_of(env) -> float:
    return float(env.unwrapped.system.parameters["m2"])


@pytest.fixture
def identified(tmp_path):
    """A small file in agents.identify's format: m2 off nominal, friction reported."""
    path = tmp_path / "parameters.yml"
    text = {"env_id": ARM, "parameters": {"m2": 1.4, "g": 9.81},
            "friction": {"q1": {"viscous": 0.1}}}  # fmt: skip
    path.write_text(yaml.safe_dump(text))
    return path


def test_a_file_is_read_in_either_form_and_applied_within_the_block(identified, tmp_path):
    with pytest.warns(UserWarning, match="friction estimates are not parameters"):
        values = params.load(identified, ARM)
    assert values == {"m2": 1.4, "g": 9.81}
    plain = tmp_path / "plain.yml"
    plain.write_text("m2: 2\n")
    assert params.load(plain, ARM) == {"m2": 2.0}
    nominal = m2_of(gym.make(ARM))
    assert nominal != 1.4
    with params.applied(ARM, values):
        assert m2_of(gym.make(spec(ARM))) == 1.4
        venv = gym.make_vec(spec(ARM), num_envs=2, vectorization_mode="vector_entry_point")
        assert float(venv.unwrapped.system.parameters["m2"]) == 1.4
        assert params.tag(ARM).startswith("_params-") and params.current(ARM) == values
        assert m2_of(gym.make(ARM)) == nominal  # Gymnasium's registry is never written
        assert "m2" not in gym.spec(ARM).kwargs
    assert m2_of(gym.make(ARM)) == nominal and params.tag(ARM) == ""  # restored


@pytest.mark.parametrize(
    "text, message",
    [
        (
            "m22: 1.4\n",
            "unknown parameter 'm22' of Lagrange/TwoLinkArm-v1's model. Did you mean 'm2'?",
        ),  # fmt: skip
        ("m2: .nan\n", "m2 must be a finite number, got nan"),
        ("m2: heavy\n", "m2 must be a finite number, got 'heavy'"),
        ("m2: true\n", "m2 must be a finite number, got True"),
        ("- m2\n", "should map parameter names to numbers"),
        ("m2: [1\n", "is not valid YAML (line 2)"),
    ],
)
def test_bad_files_are_refused_in_one_line(tmp_path, text, message):
    path = tmp_path / "p.yml"
    path.write_text(text)
    with pytest.raises(UserError, match=r"^--params: ") as exc:
        params.load(path, ARM)
    assert message in str(exc.value) and "\n" not in str(exc.value)


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_every_command_refuses_a_missing_file_before_work(name, tmp_path, capsys):
    where = {"train": ["--run-dir", str(tmp_path / "run")], "check": ["--out", str(tmp_path)],
             "evaluate": ["--agent", "zero"]}  # fmt: skip
    argv = [ARM, "--params", str(tmp_path / "nowhere.yml"), *where.get(name, [])]
    with pytest.raises(SystemExit) as exc:
        code = COMMANDS[name](argv)
        raise SystemExit(code)
    err = capsys.readouterr().err.strip()
    assert exc.value.code == 2 and len(err.splitlines()) == 1
    assert f"--params: no file {tmp_path / 'nowhere.yml'}." in err
    assert not (tmp_path / "run").exists() and not (tmp_path / "train").exists()


def test_lqr_and_evaluate_run_on_the_parameters_of_the_file(tmp_path, capsys):
    path = tmp_path / "p.yml"
    path.write_text("m2: 1.4\n")
    assert lqr.main([ARM, "--params", str(path), "--episodes", "2"]) == 0
    assert "LQR at the operating point" in capsys.readouterr().out
    assert evaluate.main([ARM, "--agent", "zero", "--episodes", "2", "--params", str(path)]) == 0
    assert f"zero on {ARM} (parameters from {path}):" in capsys.readouterr().out


@pytest.mark.slow
def test_a_run_records_its_parameters_and_resumes_only_with_them(tmp_path):
    small = dict(algo="ppo", n_envs=1, eval_freq=512, eval_episodes=2, progress=False)
    with params.applied(ARM, {"m2": 1.4}):
        train.train(ARM, timesteps=512, run_dir=tmp_path, **small)
    config = yaml.safe_load((tmp_path / "config.yml").read_text())
    assert config["env_options"] == {"parameters": {"m2": 1.4}}
    with params.applied(ARM, {"m2": 1.5}), pytest.raises(UserError, match="m2=1.4, not m2=1.5"):
        train.train(ARM, timesteps=1024, run_dir=tmp_path, resume=True, **small)
    with pytest.raises(UserError, match="m2=1.4, not none"):
        train.train(ARM, timesteps=1024, run_dir=tmp_path, resume=True, **small)


def test_check_names_its_run_and_report_by_the_parameters(tmp_path):
    with params.applied(ARM, {"m2": 1.4}):
        tag = params.tag(ARM)
        assert check.report_dir(tmp_path, [ARM], 64).name == f"Lagrange-TwoLinkArm-v1_64steps{tag}"
