"""RL handing over to LQR: the capture level, the training wrapper's switch and shaping, and
the trained agent's switch after save and load."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from agents.common import UserError
from agents.control.handover import CaptureSet, HandOverPolicy, HandOverVecEnv, handover_options
from agents.evaluate import make_agent
from agents.learning import hparams
from agents.learning.vecenv import make_sb3_vec_env
from agents.train import train

ACROBOT = "Lagrange/Acrobot-v2"


def _level() -> float:
    return hparams.load("ppo", ACROBOT)["handover"]["level"]


def test_lqr_captures_from_the_declared_level_set():
    episodes = 200
    vec = gym.make_vec(ACROBOT, num_envs=episodes, vectorization_mode="vector_entry_point")
    try:
        vec.reset(seed=0)
        capture = CaptureSet(vec, _level())
        x0, u0 = vec.unwrapped.operating_point()
        P = capture.lqr.design(x0[0], u0[0]).P
        z = np.random.default_rng(0).normal(size=(episodes, 4))
        dx = np.linalg.solve(np.linalg.cholesky(P).T, z.T).T
        dx *= np.sqrt(capture.level / np.einsum("bi,ij,bj->b", dx, P, dx))[:, None]
        obs, _ = vec.reset(seed=0, options={"state": x0 + dx, "goal": vec.unwrapped.goal})
        ended = np.zeros(episodes, dtype=bool)
        for _ in range(200):  # 10 s, five times the slowest closed-loop time constant
            obs, _, terminated, _, info = vec.step(capture.lqr.predict(obs)[0])
            ended |= terminated
    finally:
        vec.close()
    # measured on these 200 directions: 100 % at level 500, 97.5 % at 1000, 73.5 % at 2000
    # (96.1 % of 1000 directions at 1000). The edge of the set is where the saturated LQR
    # starts to fail; a state that enters and escapes goes back to the learnt policy, so
    # the level may sit where a few percent fail, not where most do.
    assert (info["is_success"] & ~ended).mean() >= 0.95


def test_verified_capture_is_what_the_env_does_under_lqr():
    # the check simulates the env's own model, so it must agree row for row with LQR run in
    # the env itself, for states spread between the level set and the verify level
    episodes, horizon = 60, 3.0
    vec = gym.make_vec(ACROBOT, num_envs=episodes, vectorization_mode="vector_entry_point")
    try:
        obs, _ = vec.reset(seed=0)
        capture = CaptureSet(vec, _level(), verify=horizon)
        x0, u0 = vec.unwrapped.operating_point()
        P = capture.lqr.design(x0[0], u0[0]).P
        z = np.random.default_rng(1).normal(size=(episodes, 4))
        dx = np.linalg.solve(np.linalg.cholesky(P).T, z.T).T
        levels = capture.level * np.geomspace(1.0, 20.0, episodes)
        dx *= np.sqrt(levels / np.einsum("bi,ij,bj->b", dx, P, dx))[:, None]
        goals = vec.unwrapped.goal
        obs, _ = vec.reset(seed=0, options={"state": x0 + dx, "goal": goals})
        _, _, _, cost = capture.cost(obs)
        checked = capture.captures(vec.unwrapped.state, goals, x0, u0)
        ended = np.zeros(episodes, dtype=bool)
        for _ in range(capture.verify_steps):
            a = capture.lqr.act(vec.unwrapped.state, x0, u0)  # exact states, as simulated
            obs, _, terminated, _, info = vec.step(a)
            ended |= terminated
    finally:
        vec.close()
    np.testing.assert_array_equal(checked, info["is_success"] & ~ended)
    assert 0 < checked.sum() < episodes  # both answers occur on this spread of levels
    assert capture.simulated == episodes
    assert np.all(cost >= capture.level * 0.999)  # none of them inside the ellipsoid


class Constant:
    """A stand-in for a trained model: the same action everywhere."""

    def __init__(self, value: float):
        self.value = value

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        obs = np.asarray(observation)  # like SB3: a batch in, a batch out; one in, one out
        return np.full(obs.shape[:-1] + (1,), self.value, dtype=np.float32), state


def test_the_policy_is_lqr_inside_the_set_and_the_model_outside():
    env = gym.make(ACROBOT)
    policy = HandOverPolicy(Constant(0.7), env, _level())
    lqr = policy.capture.lqr
    env.reset(seed=0)
    up = np.array([np.pi + 0.005, np.pi - 0.005, 0.01, 0.0])
    obs = np.stack(
        [env.reset(options={"state": x})[0] for x in (up, np.zeros(4), np.array([np.pi, 0, 0, 0]))]
    )
    actions, _ = policy.predict(obs)
    x0, u0 = env.unwrapped.operating_point(obs)
    assert actions.shape == (3, 1)
    assert lqr.cost_to_go(up, x0[0], u0[0])[0] < policy.capture.level
    np.testing.assert_allclose(actions[0], lqr.act(up, x0[0], u0[0])[0], rtol=1e-6)
    np.testing.assert_array_equal(actions[1:], np.float32(0.7))
    single, _ = policy.predict(obs[0])
    assert single.shape == (1,) and single[0] == actions[0, 0]


def test_training_env_switches_and_its_shaping_telescopes():
    # undiscounted shaping sums to Phi(last) - Phi(first) over a truncated episode
    level, shaping = _level(), 100.0
    venv = HandOverVecEnv(make_sb3_vec_env(ACROBOT, 2, 0, "native"), level, shaping, gamma=1.0)
    plain = make_sb3_vec_env(ACROBOT, 2, 0, "native")
    obs, obs_plain = venv.reset(), plain.reset()
    np.testing.assert_array_equal(obs, obs_plain)
    first = venv._potential(obs)
    rng = np.random.default_rng(0)
    gained = np.zeros(2)
    for _ in range(500):  # the time limit: both copies truncate at the last step
        a = rng.uniform(-0.3, 0.3, (2, 1)).astype(np.float32)  # gentle: no copy diverges
        switched, inside = venv.capture.override(obs, a)
        obs, r, done, infos = venv.step(a)
        obs_plain, r_plain, _, _ = plain.step(switched)  # what the wrapper sent on
        np.testing.assert_array_equal(obs, obs_plain)
        gained += r.astype(np.float64) - r_plain
    assert done.all() and all(i["TimeLimit.truncated"] for i in infos)
    last = venv._potential(np.stack([i["terminal_observation"] for i in infos]))
    # float32 rewards: 500 steps of rounding at |r| <= 14 leave ~1e-3
    np.testing.assert_allclose(gained, last - first, atol=1e-2)
    assert np.all(first < -50)  # the hanging start is far from the goal's energy


@pytest.mark.slow  # trains (3 s): the fast suite stays under a minute
def test_a_trained_run_with_handover_acts_through_lqr_after_loading(tmp_path):
    run = train(
        ACROBOT, "ppo", timesteps=512, n_envs=1, run_dir=tmp_path, eval_freq=512,
        eval_episodes=1, progress=False,
    )  # fmt: skip
    assert run.timesteps == 512
    vec = gym.make_vec(ACROBOT, num_envs=2, vectorization_mode="vector_entry_point")
    agent = make_agent(str(tmp_path), vec)
    assert isinstance(agent, HandOverPolicy) and agent.capture.level == _level()
    vec.close()


@pytest.mark.parametrize(
    "raw",
    [
        {"shaping": 1.0},
        {"level": -1.0},
        {"level": 5.0, "shaping": -1},
        {"level": 5.0, "verify": float("nan")},
        {"level": 5.0, "verify": 1e9},  # would simulate for years inside one step
        {"level": 5.0, "verify_level": 1.0},
        {"level": "high"},
        [500],
        {"x": 1},
    ],
)
def test_bad_handover_options_are_refused(raw):
    with pytest.raises(UserError, match="handover"):
        handover_options(raw)


def test_handover_options_default_to_no_shaping():
    assert handover_options(None) is None
    assert handover_options({"level": 500}) == {
        "level": 500.0,
        "verify_level": 10000.0,
        "shaping": 0.0,
        "verify": 0.0,
    }
