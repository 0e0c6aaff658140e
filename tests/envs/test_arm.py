"""Lagrange/TwoLinkArm-v1: the goal-error columns of the observation and the reward terms."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401  (registers the Lagrange ids)


def test_error_columns_are_the_wrapped_goal_errors():
    env = gym.make("Lagrange/TwoLinkArm-v1").unwrapped
    rng = np.random.default_rng(0)
    for _ in range(20):
        # angles beyond [-pi, pi) too: the errors must be wrapped, not raw differences
        x = np.concatenate([rng.uniform(-10, 10, 2), rng.uniform(-1, 1, 2)])
        goal = rng.uniform(-np.pi, np.pi, 2)
        obs, _ = env.reset(options={"state": x, "goal": goal})
        # the columns: cos/sin of theta1, theta2, rates, goal angles, then of the goal errors
        e = np.arctan2(obs[[11, 13]], obs[[10, 12]])
        expected = (x[:2] - goal + np.pi) % (2 * np.pi) - np.pi
        # float32 observation: cos/sin rounded to ~6e-8, so the recovered angle to ~1e-6
        np.testing.assert_allclose(e, expected, atol=1e-5)


@pytest.mark.parametrize("error", [(0.3, -0.4), (-2.0, 1.0), (0.05, 0.0)])
def test_reward_terms_at_rest(error):
    # control_period 1e-9 s: the state does not move (rates 0, accelerations ~10 rad/s^2)
    env = gym.make("Lagrange/TwoLinkArm-v1", control_period=1e-9).unwrapped
    goal = np.array([0.5, -1.0])
    x = np.concatenate([goal + np.array(error), [0.0, 0.0]])
    env.reset(options={"state": x, "goal": goal})
    _, r, _, _, info = env.step(np.zeros(2, np.float32))
    terms = info["reward_terms"]
    e = np.array(error)
    # 1e-12: the same float64 expressions, up to the ~1e-17 rad the step moved the arm
    assert terms["angle"] == pytest.approx(-(e @ e), abs=1e-12)
    assert terms["precision"] == pytest.approx(-np.linalg.norm(e), abs=1e-12)
    assert terms["rate"] == pytest.approx(0.0, abs=1e-12)
    assert terms["effort"] == 0.0
    assert info["is_success"] == bool(np.all(np.abs(e) < 0.1))
