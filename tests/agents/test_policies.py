"""The baselines: SB3's predict interface, and the physics each one relies on."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import envs
from agents.evaluate import HEURISTICS, evaluate, make_agent
from agents.policies import GravityPDPolicy, SB3Policy, SwingUpPolicy, input_response


@pytest.mark.parametrize("env_id", envs.ENV_IDS)
@pytest.mark.parametrize("name", ["random", "zero", "heuristic", "lqr"])
def test_every_baseline_answers_predict_for_one_and_a_batch(env_id, name):
    env = gym.make(env_id)
    if name == "heuristic" and env_id not in HEURISTICS:
        with pytest.raises(ValueError, match="No heuristic baseline"):
            make_agent(name, env)
        return
    policy = make_agent(name, env, seed=0)
    obs, _ = env.reset(seed=0)
    action, state = policy.predict(obs, deterministic=True)
    assert action.shape == env.action_space.shape and state is None
    assert env.action_space.contains(action)
    batch = np.stack([obs] * 3)
    actions, _ = policy.predict(batch, deterministic=True)
    assert actions.shape == (3,) + env.action_space.shape
    if name != "random":  # a deterministic policy answers each row of a batch alike
        np.testing.assert_allclose(actions[0], action, rtol=0, atol=1e-6)


def test_gravity_compensation_holds_the_arm_at_rest_where_it_is():
    # At the goal and at rest the PD terms vanish: what is left must hold the arm still.
    env = gym.make("Lagrange/TwoLinkArm-v0")
    q = np.array([0.7, -1.2])
    x = np.concatenate([q, [0.0, 0.0]])
    obs, _ = env.reset(seed=0, options={"state": x, "goal": q})
    policy = GravityPDPolicy(env)
    for _ in range(20):
        action, _ = policy.predict(obs)
        obs, *_ = env.step(action)
    # RK4 at 2 ms substeps on a state that should not move: any drift is integration and
    # float32 action rounding (~1e-7 relative torque), far below a visible 1e-4 rad
    np.testing.assert_allclose(env.unwrapped.state, x, atol=1e-4)


def test_input_response_is_exact_because_accelerations_are_affine_in_the_inputs():
    env = gym.make("Lagrange/TwoLinkArm-v0")
    system = env.unwrapped.system
    x = np.array([[0.3, 2.0, 1.0, -0.5]])
    a0, Bq = input_response(system, x, [0, 1])
    u = np.array([[3.0, -2.0]])
    expected = system.accelerations(0.0, x, u)
    # affine: two evaluations predict every other input to rounding (1e-12 of ~10 rad/s^2)
    np.testing.assert_allclose(a0 + (Bq @ u[..., None])[..., 0], expected, atol=1e-10)


def test_swing_up_pumps_energy_monotonically_towards_the_inverted_energy():
    env = gym.make("Lagrange/Acrobot-v0")
    policy = SwingUpPolicy(env, k_p=0.0, k_d=0.0, capture_angle=0.0)  # energy term alone
    obs, _ = env.reset(seed=0, options={"state": [0.1, -0.1, 0.0, 0.5]})
    target = env.unwrapped.system.energy(env.unwrapped.operating_point()[0])
    energies = [env.unwrapped.system.energy(env.unwrapped.state)]
    while energies[-1] < target - 1.0 and len(energies) < 200:
        action, _ = policy.predict(obs)
        obs, _, _, _, info = env.step(action)
        energies.append(info["energy"])
    # dE/dt = k (E* - E) |p|^2 >= 0 in continuous time; with the action held over a 50 ms
    # step, p changes sign within a step now and then, so allow a small loss per step
    assert np.diff(energies).min() > -0.05 * (target - energies[0])
    assert energies[-1] > target - 1.0, "the energy never came within 1 J of E*"


@pytest.mark.parametrize(
    "env_id", ["Lagrange/TwoLinkArm-v0", "Lagrange/BeadOnRod-v0", "Lagrange/CrankSlider-v0"]
)
def test_model_based_heuristics_solve_their_tasks(env_id):
    stats = evaluate(env_id, "heuristic", episodes=5, seed=0)
    assert stats.success_rate == 1.0
    assert stats.mean_return > evaluate(env_id, "zero", episodes=5, seed=0).mean_return


def test_gravity_pd_refuses_an_underactuated_model():
    with pytest.raises(ValueError, match="one actuated input per coordinate"):
        GravityPDPolicy(gym.make("Lagrange/Acrobot-v0"))


def test_sb3_policy_applies_the_saved_observation_statistics():
    class Echo:  # a model whose action is the observation it was given
        def predict(self, obs, state=None, episode_start=None, deterministic=True):
            return obs, state

    class Stats:
        mean = np.array([1.0, -2.0])
        var = np.array([4.0, 0.25])

    policy = SB3Policy(Echo(), Stats(), clip_obs=10.0, epsilon=0.0)
    action, _ = policy.predict(np.array([3.0, 100.0]))
    np.testing.assert_allclose(action, [1.0, 10.0])  # (3-1)/2, and (100+2)/0.5 clipped


def test_loading_a_missing_model_names_the_path(tmp_path):
    with pytest.raises(FileNotFoundError, match="No trained model"):
        SB3Policy.load(tmp_path / "nothing.zip")
