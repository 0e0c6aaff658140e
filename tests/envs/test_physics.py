"""The physics inside the environments is the model's: energy, constraints, equilibria."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401  (registers the ids)

# per env: the energy scale the drift is measured against (J) and the bound on the relative
# drift over one unforced episode that its docstring states (each about 3x the largest drift
# measured over these 100 episodes, so a change of integrator or step shows; the
# acrobot's is round-off)
ENERGY = {
    # potential-energy range of the default arm: 2 (m1 g l1 + m2 g (l + l2)) = 39.24 J
    "Lagrange/TwoLinkArm-v1": (39.24, 3e-8),
    "Lagrange/Acrobot-v1": (39.24, 1e-12),
    # the disk's own energy (kinetic + m g r, a few J)
    "Lagrange/RollingDisk-v1": (None, 1e-9),
    # m g rod_length / 2 for the default bead (0.98 J)
    "Lagrange/BeadOnRod-v1": (0.981, 5e-12),
    # M g |s| for the default eccentric disk (0.98 J)
    "Lagrange/CrankSlider-v1": (0.981, 3e-12),
}


@pytest.mark.parametrize("env_id", list(ENERGY))
def test_zero_torque_episode_conserves_energy(env_id):
    scale, bound = ENERGY[env_id]
    n = 100
    vec = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point")
    _, info = vec.reset(seed=0)
    e0 = info["energy"]
    ref = np.abs(e0) if scale is None else scale
    alive = np.ones(n, dtype=bool)
    worst = 0.0
    zero = np.zeros(vec.action_space.shape)
    for _ in range(vec.unwrapped.max_episode_steps):
        _, _, term, trunc, info = vec.step(zero)
        assert not info["diverged"].any()
        drift = np.abs(info["energy"] - e0) / ref
        worst = max(worst, drift[alive].max(initial=0.0))
        alive &= ~(term | trunc)  # the next step resets these copies
        if not alive.any():
            break
    assert worst <= bound, f"relative energy drift {worst:.2e} > documented {bound:.0e}"


def test_disk_constraint_residual_stays_at_round_off():
    vec = gym.make_vec(
        "Lagrange/RollingDisk-v1", num_envs=50, vectorization_mode="vector_entry_point"
    )
    vec.reset(seed=1)
    rng = np.random.default_rng(0)
    worst = 0.0
    for _ in range(200):
        _, _, _, _, info = vec.step(rng.uniform(-1, 1, (50, 2)))
        worst = max(worst, np.abs(info["constraint_residual"]).max())
    # each substep is projected onto the constraints: a few ulps of speeds ~ 1 m/s
    assert worst < 1e-13


def test_arm_holds_a_goal_with_its_operating_input():
    env = gym.make("Lagrange/TwoLinkArm-v1").unwrapped
    goal = np.array([2.0, -2.5])
    env.reset(seed=0, options={"goal": goal, "state": np.r_[goal, 0.0, 0.0]})
    x0, u0 = env.operating_point()
    a = env.input_to_action(u0)
    for _ in range(10):  # an unstable equilibrium: held for 0.5 s by the exact static torque
        _, _, _, _, info = env.step(a)
    # growth of round-off (1e-16) over 0.5 s at unstable rates of a few 1/s
    np.testing.assert_allclose(info["state"], x0, atol=1e-10)
    assert info["is_success"]


def test_acrobot_cannot_hold_link_two_horizontal():
    env = gym.make("Lagrange/Acrobot-v1").unwrapped
    p = env.system.parameters
    assert env.max_input[0] < p["m2"] * p["g"] * p["l2"]


def test_disk_rolls_straight_at_the_command_without_torque():
    env = gym.make("Lagrange/RollingDisk-v1").unwrapped
    goal = np.array([2.0, 0.7])
    env.reset(seed=0, options={"goal": goal})
    x0, u0 = env.operating_point()
    np.testing.assert_allclose(u0, 0, atol=1e-12)  # needs no torque (round-off of a solve)
    env.reset(options={"goal": goal, "state": x0})
    for _ in range(40):  # 2 s; above the critical speed, upright rolling is stable
        _, r, term, _, info = env.step(np.zeros(2))
    assert not term and info["is_success"]
    x = info["state"]
    # the contact point travelled v t along the heading (2 m/s for 2 s); RK4 error ~1e-9
    np.testing.assert_allclose(x[:2], 4.0 * np.array([np.sin(0.7), np.cos(0.7)]), atol=1e-6)


def test_crank_operating_point_puts_the_slider_on_target_on_the_nearer_branch():
    env = gym.make("Lagrange/CrankSlider-v1").unwrapped
    for theta in (1.0, -1.0):
        env.reset(seed=0, options={"state": [theta, 0.0], "goal": [0.3]})
        x0, u0 = env.operating_point()
        slider = env.system.outputs(0.0, x0)["slider_x"]
        assert slider == pytest.approx(0.3, abs=1e-12)  # bisection to round-off
        assert np.sign(x0[0]) == np.sign(theta)  # the branch on the current side
        p = env.system.parameters
        # gravity acts on the disk only: the holding torque is M g s cos(theta)
        assert u0[0] == pytest.approx(p["M"] * p["g"] * p["s"] * np.cos(x0[0]), rel=1e-9)
        env.reset(options={"state": x0, "goal": [0.3]})
        for _ in range(10):
            _, _, _, _, info = env.step(env.input_to_action(u0))
        # held at rest for 0.5 s: only round-off grows (the equilibrium may be unstable)
        np.testing.assert_allclose(info["state"], x0, atol=1e-9)


def test_bead_terminates_when_it_leaves_the_rod():
    env = gym.make("Lagrange/BeadOnRod-v1").unwrapped
    env.reset(seed=0, options={"state": [0.9, 0.0, 2.0, 0.0]})
    _, _, term, _, info = env.step(np.zeros(1))
    assert term and abs(info["state"][0]) > 1.0
    env.reset(seed=0, options={"state": [0.5, 0.0, 0.0, 0.0], "goal": [0.5]})
    x0, u0 = env.operating_point()
    # holding the bead at r on the level rod takes m g r
    assert u0[0] == pytest.approx(0.1 * 9.81 * 0.5, rel=1e-12)
    with pytest.raises(ValueError, match=r"'r\*' must lie in"):
        env.reset(options={"goal": [1.5]})
