"""The feed-forward of the holding input (agents.learning.feedforward): what it adds, in
training, in its evaluations and in a loaded agent."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import examples.three_link_arm  # noqa: F401  (registers Examples/ThreeLinkArm-v0)
from agents.common import lagrange_env
from agents.learning import hparams
from agents.learning.feedforward import FeedForwardPolicy, FeedForwardVecEnv, operating_action
from agents.learning.vecenv import make_envs

ARM = "Examples/ThreeLinkArm-v0"


def test_the_holding_action_holds_any_configuration_at_rest():
    # gravity's torque at the arm's configuration: with it alone the arm, started at rest
    # anywhere within its motors' reach, stays there. 1e-6 rad over 1 s is round-off of
    # the integrator against a displacement that gravity alone would make of order 1 rad
    env = gym.make_vec(ARM, num_envs=4, vectorization_mode="vector_entry_point")
    base = lagrange_env(env)
    obs, _ = env.reset(seed=0)
    x = np.zeros((4, 6))
    x[:, :3] = np.random.default_rng(0).uniform(-0.6, 0.6, (4, 3))
    goal = base.plant.goal_from_observation(obs)
    obs, _ = env.reset(options={"state": x, "goal": goal})
    assert np.abs(operating_action(base, obs)).max() > 0.05  # not trivially zero
    for _ in range(50):
        obs, *_ = env.step(operating_action(base, obs).astype(np.float32))
    assert np.abs(base.state_from_observation(obs)[:, :3] - x[:, :3]).max() < 1e-6
    zero = env.reset(options={"state": x, "goal": goal})[0]
    for _ in range(50):
        zero, *_ = env.step(np.zeros((4, 3), dtype=np.float32))
    assert np.abs(base.state_from_observation(zero)[:, :3] - x[:, :3]).max() > 0.01
    env.close()


def test_training_and_its_evaluations_add_it_to_the_agents_action():
    hp = {**hparams.load("ppo", ARM), "feedforward": True, "normalize": False}
    train, evaluation = make_envs(ARM, {**hp, "n_envs": 2}, 2, 0, "auto", 2)
    plain, _ = make_envs(ARM, {**hp, "feedforward": False}, 2, 0, "auto", 2)
    for venv in (train, evaluation):
        inner = venv
        while not isinstance(inner, FeedForwardVecEnv):
            inner = inner.venv
    obs_f, obs_p = train.reset(), plain.reset()
    np.testing.assert_array_equal(obs_f, obs_p)
    base = inner.env
    a = np.full((2, 3), 0.1, dtype=np.float32)
    obs_f, *_ = train.step(a)
    obs_p, *_ = plain.step(np.clip(a + operating_action(base, obs_p), -1, 1).astype(np.float32))
    np.testing.assert_allclose(obs_f, obs_p, rtol=1e-6, atol=1e-7)
    for venv in (train, evaluation, plain):
        venv.close()


def test_a_loaded_agent_acts_with_it(tmp_path):
    from agents.evaluate import make_agent
    from agents.train import train

    yml = tmp_path / "ff.yml"
    yml.write_text(f"{ARM}:\n  feedforward: true\n  n_envs: 2\n  n_steps: 64\n  batch_size: 64\n")
    run = tmp_path / "run"
    train(ARM, timesteps=128, run_dir=run, hyperparams=yml, progress=False, eval_freq=10**6)
    env = gym.make_vec(ARM, num_envs=2, vectorization_mode="vector_entry_point")
    agent = make_agent(str(run), env, 0)
    assert isinstance(agent, FeedForwardPolicy)
    obs, _ = env.reset(seed=3)
    raw, _ = agent.policy.predict(obs)
    acted, _ = agent.predict(obs)
    expected = np.clip(raw + operating_action(lagrange_env(env), obs), -1, 1)
    np.testing.assert_allclose(acted, expected, rtol=1e-6)
    env.close()
    # a loaded policy object handed to evaluate acts as the run's path does: with it
    from agents.evaluate import evaluate
    from agents.scoring.trained import SB3Policy

    by_path, by_object = evaluate(ARM, str(run), 2, 5), evaluate(ARM, SB3Policy.load(run), 2, 5)
    np.testing.assert_array_equal(by_path.returns, by_object.returns)


@pytest.mark.parametrize("value", ["yes", 1, None])
def test_feedforward_is_true_or_false(value):
    with pytest.raises(hparams.UserError, match="feedforward"):
        hparams.check_entries({"feedforward": value}, "my.yml (default)")
    assert hparams.check_entries({"feedforward": True}, "f") == {"feedforward": True}


@pytest.mark.parametrize(
    "env_id, holds",
    [
        (ARM, True),  # three motors, three joints
        ("Lagrange/TwoLinkArm-v1", True),
        ("Lagrange/CrankSlider-v1", True),  # one motor, one coordinate
        ("Lagrange/Acrobot-v2", False),  # two inputs declared, the shoulder's not actuated
        ("Examples/Kapitza-v0", False),  # one motor, but its pivot is driven in time
        ("Lagrange/RollingDisk-v1", False),  # rolling constraints
        ("Lagrange/BeadOnRod-v1", False),  # the bead is not actuated
    ],
)
def test_it_is_derived_where_the_inputs_hold_every_configuration_at_rest(env_id, holds):
    import examples.kapitza  # noqa: F401
    from agents.learning.feedforward import holds_at_rest

    env = gym.make(env_id)
    assert holds_at_rest(env.unwrapped.plant) is holds
    env.close()
    assert bool(hparams.load("ppo", env_id).get("feedforward")) is holds


def test_a_users_file_turns_it_off(tmp_path):
    from agents.learning.defaults import describe

    yml = tmp_path / "off.yml"
    yml.write_text(f"{ARM}:\n  feedforward: false\n")
    assert "holding input fed forward" in describe(hparams.load("ppo", ARM))
    hp = hparams.load("ppo", ARM, yml)
    assert hp["feedforward"] is False
    assert "fed forward" not in describe(hp)
