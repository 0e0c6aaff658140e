"""docs/new-system.md stays true: its code, pasted into a module as the page says, builds an
env that the agents serve."""

from __future__ import annotations

import importlib
import re
import sys
import warnings
from pathlib import Path

import gymnasium as gym
import pytest

import envs.docs

PAGE = Path(__file__).resolve().parents[1] / "docs" / "new-system.md"


@pytest.mark.slow  # derives the model: seconds cold
def test_the_new_system_walkthrough_runs_as_written(tmp_path, monkeypatch, capsys):
    blocks = re.findall(r"```python\n(.*?)```", PAGE.read_text(encoding="utf-8"), re.S)
    (tmp_path / "my_cart_pole.py").write_text("\n\n".join(blocks), encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    sys.modules.pop("my_cart_pole", None)
    module = importlib.import_module("my_cart_pole")
    env = gym.make("MyNS/CartPole-v0", m_pole=0.2)
    obs, _ = env.reset(seed=0)
    assert obs.shape == (5,) and env.unwrapped.system.parameters["m_pole"] == 0.2
    assert "| 0 | F | 10 |" in envs.docs.describe(module.TASK)
    from agents import lqr

    assert lqr.main(["my_cart_pole:MyNS/CartPole-v0", "--episodes", "10"]) == 0
    assert "LQR: success 10/10" in capsys.readouterr().out
    _the_next_steps_work_as_the_page_says()


def _the_next_steps_work_as_the_page_says():
    """Part 5: a goal drawn at reset with the operating point on it, a derived feature, a
    model output, a force at a point, a one-sided input, a nonholonomic constraint."""
    import numpy as np

    env = gym.make("MyNS/CartPoleTarget-v0")
    obs, info = env.reset(seed=1)
    goal = float(info["goal"][0])
    assert -1.0 <= goal <= 1.0 and obs.shape == (7,)
    x = env.unwrapped.state
    assert obs[5] == pytest.approx(goal) and obs[6] == pytest.approx(x[0] - goal, abs=1e-6)
    x0, _ = env.unwrapped.operating_point()
    assert x0[0] == pytest.approx(goal)  # the operating point follows the goal

    with warnings.catch_warnings():  # the named start and operating point: no former form
        warnings.simplefilter("error", DeprecationWarning)
        env = gym.make("MyNS/CartPoleNearTarget-v0")
    _, info = env.reset(seed=2)
    goal, x = float(info["goal"][0]), env.unwrapped.state
    assert abs(x[0] - goal) <= 0.5 and abs(x[1]) <= 0.1 and not x[2:].any()
    assert env.unwrapped.operating_point()[0][0] == goal

    env = gym.make("MyNS/CartPoleThruster-v0")
    obs, info = env.reset(seed=0)
    _, _, _, _, info = env.step(np.array([0.0, -1.0], np.float32))
    assert info["input"][1] == 0.0  # action -1 is the thruster's 0 N: it never pulls
    _, _, _, _, info = env.step(np.array([0.0, 1.0], np.float32))
    assert info["input"][1] == pytest.approx(2.0)
    l = env.unwrapped.system.parameters["l"]
    assert obs[5] == pytest.approx(2 * l * np.cos(env.unwrapped.state[1]), abs=1e-3)  # tip_height

    env = gym.make("MyNS/Skate-v0")
    env.reset(seed=0)
    for _ in range(20):
        _, _, _, _, info = env.step(np.array([1.0, 0.5], np.float32))
    x = env.unwrapped.state
    sideways = -np.sin(x[2]) * x[3] + np.cos(x[2]) * x[4]
    # the constraint holds to the integrator's projection: round-off, not slip
    assert abs(sideways) < 1e-9 and np.abs(info["constraint_residual"]).max() < 1e-9
    assert np.hypot(x[3], x[4]) > 0.1  # it moved, along its heading


def test_ci_runs_the_readme_test_command_word_for_word():
    root = PAGE.parents[1]
    blocks = re.findall(r"```bash\n(.*?)```", (root / "README.md").read_text(), re.S)
    command = next(b.strip() for b in blocks if "pytest" in b and "venv" in b)
    assert command in (root / ".ci" / "run").read_text().splitlines()
