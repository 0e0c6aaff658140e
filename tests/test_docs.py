"""docs/new-system.md stays true: its code, pasted into a module as the page says, builds an
env that the agents serve."""

from __future__ import annotations

import importlib
import re
import sys
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


def test_ci_runs_the_readme_test_command_word_for_word():
    root = PAGE.parents[1]
    blocks = re.findall(r"```bash\n(.*?)```", (root / "README.md").read_text(), re.S)
    command = next(b.strip() for b in blocks if "pytest" in b and "venv" in b)
    assert command in (root / ".ci" / "run").read_text().splitlines()
