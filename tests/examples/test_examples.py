"""Systems beyond the book, written as a user would (examples/): the Gymnasium and SB3
checkers, LQR from the linearised equations, the line budget, energy, and differential
tests against the equations users already trust (Gymnasium's CartPole-v1 and Acrobot-v1)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import dynamics
from agents.control.policies import ZeroPolicy
from agents.scoring import closed_loop
from examples import cart_pole, double_cart_pole, furuta
from tests.examples.checkers import assert_both_checkers_pass

EXAMPLES = {
    "Examples/CartPole-v0": cart_pole,
    "Examples/Furuta-v0": furuta,
    "Examples/DoubleCartPole-v0": double_cart_pole,
}
IDS = list(EXAMPLES)


@pytest.mark.parametrize("env_id", IDS)
def test_each_example_reads_its_inputs_by_name(env_id):
    # the examples are written on exactly the API a user gets: a function per reward term
    task = EXAMPLES[env_id].TASK
    assert task.reward is None and all(t.fn is not None for t in task.terms)


@pytest.mark.parametrize("env_id", IDS)
def test_both_checkers_pass(env_id):
    assert_both_checkers_pass(env_id)


@pytest.mark.parametrize("env_id", IDS)
def test_lqr_holds_the_stated_start_region_and_zero_torque_does_not(env_id):
    # 100 seeded episodes from the operating point perturbed within the task's LQR region
    lqr = closed_loop.evaluate_near(env_id, episodes=100, seed=0)
    zero = closed_loop.evaluate_near(env_id, ZeroPolicy, episodes=100, seed=0)
    assert lqr.success_rate >= 0.99
    assert zero.success_rate == 0.0  # measured: every unforced pole falls


@pytest.mark.parametrize("env_id", IDS)
def test_an_unforced_episode_conserves_energy(env_id):
    vec = gym.make_vec(env_id, 20, vectorization_mode="vector_entry_point")
    _, info = vec.reset(seed=0)
    e0 = info["energy"].copy()
    alive = np.ones(20, dtype=bool)
    worst = 0.0
    scale = np.abs(e0).max()
    for _ in range(100):
        _, _, term, trunc, info = vec.step(np.zeros(vec.action_space.shape))
        worst = max(worst, np.abs(info["energy"] - e0)[alive].max(initial=0.0) / scale)
        alive &= ~(term | trunc)
    # RK4 at the task's substep: a few 1e-9 of the energy over the fall (measured ~1e-10)
    assert worst < 1e-7


def test_cart_pole_matches_gymnasium_cartpole_v1():
    """The derived cart-pole against CartPole-v1's own update, parameter by parameter:
    masscart -> m_cart, masspole -> m_pole, length (half the pole) -> l, gravity -> g,
    force_mag -> F = +-10 N. Conventions: both measure theta from upright, positive as the
    pole tips towards +x. CartPole-v1 integrates with explicit Euler, so its accelerations
    are (x_dot' - x_dot) / tau, exact to ~1e-14 relative at its tau = 0.02 s."""
    gym_env = gym.make("CartPole-v1").unwrapped
    assert gym_env.kinematics_integrator == "euler"
    system = dynamics.Model(cart_pole.cart_pole).compile(
        m_cart=gym_env.masscart, m_pole=gym_env.masspole, l=gym_env.length, g=gym_env.gravity
    )
    rng = np.random.default_rng(0)
    for _ in range(50):
        state = rng.uniform([-2, -0.2, -2, -2], [2, 0.2, 2, 2])
        action = int(rng.integers(2))
        gym_env.state, gym_env.steps_beyond_terminated = state.copy(), None
        gym_env.step(action)
        new = np.asarray(gym_env.state)
        gym_acc = (new[[1, 3]] - state[[1, 3]]) / gym_env.tau
        x = state[[0, 2, 1, 3]]  # ours: [x, theta, x', theta']
        force = gym_env.force_mag if action == 1 else -gym_env.force_mag
        ours = system.accelerations(0.0, x, [force])
        np.testing.assert_allclose(ours, gym_acc, rtol=1e-12, atol=1e-12)


def test_arm_with_acrobot_parameters_matches_gymnasium_acrobot_v1():
    """The chapter's two-link arm against Acrobot-v1's `_dsdt`, parameter by parameter:
    LINK_MASS_1/2 -> m1/m2, LINK_LENGTH_1 -> l, LINK_COM_POS_1/2 -> l1/l2, LINK_MOI (a
    central moment in its d1, d2) -> Ibar1, Ibar2, g = 9.8; the torque acts at the elbow,
    link 1 on link 2 -> M2. Conventions: both measure theta1 from the downward vertical, in
    the same sense; Acrobot-v1's theta2 is relative to link 1, ours absolute, so
    theta2_abs = theta1 + theta2_rel (and its rates)."""
    gym_env = gym.make("Acrobot-v1").unwrapped
    assert gym_env.book_or_nips == "book"
    system = dynamics.get_model("two_link_arm").compile(
        m1=gym_env.LINK_MASS_1,
        m2=gym_env.LINK_MASS_2,
        l=gym_env.LINK_LENGTH_1,
        l1=gym_env.LINK_COM_POS_1,
        l2=gym_env.LINK_COM_POS_2,
        Ibar1=gym_env.LINK_MOI,
        Ibar2=gym_env.LINK_MOI,
        g=9.8,
    )
    rng = np.random.default_rng(1)
    for _ in range(50):
        s = rng.uniform(-np.pi, np.pi, 4) * [1, 1, 3, 3]
        torque = rng.uniform(-1, 1)
        theirs = np.asarray(gym_env._dsdt(np.append(s, torque)))[2:4]
        x = np.array([s[0], s[0] + s[1], s[2], s[2] + s[3]])
        acc = system.accelerations(0.0, x, [0.0, torque])
        ours = np.array([acc[0], acc[1] - acc[0]])  # back to the relative elbow angle
        np.testing.assert_allclose(ours, theirs, rtol=1e-11, atol=1e-11)
