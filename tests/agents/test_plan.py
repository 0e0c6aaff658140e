"""Trajectory optimisation and time-varying LQR (agents.plan, agents.control.tvlqr), and the
acrobot they make solvable (Lagrange/Acrobot-v2)."""

from __future__ import annotations

import re

import gymnasium as gym
import numpy as np
import pytest

import envs
from agents import plan as planning
from agents.control.policies import input_response
from agents.control.tvlqr import PlanPolicy, tvlqr
from agents.evaluate import evaluate, make_agent

ACROBOT = "Lagrange/Acrobot-v2"


# ---- pieces ------------------------------------------------------------------------------
def test_box_qp_solves_bounded_quadratics():
    H = np.array([[2.0, 0.5], [0.5, 1.0]])
    g = np.array([-4.0, 1.0])
    x, free = planning.box_qp(H, g, np.array([-1.0, -1.0]), np.array([1.0, 1.0]))
    # x0 is held at its upper bound; x1 then minimises its own quadratic: x1 = -(1 + 0.5) / 1
    np.testing.assert_allclose(x, [1.0, -1.0], atol=1e-12)  # ... which is clipped to -1 too
    assert not free.any()
    x, free = planning.box_qp(H, g, np.full(2, -10.0), np.full(2, 10.0))
    np.testing.assert_allclose(x, np.linalg.solve(H, -g), atol=1e-10)
    assert free.all()


def test_step_jacobians_are_the_derivative_of_the_envs_step():
    env = gym.make(ACROBOT).unwrapped
    s, dt, sub = env.system, env.control_period, 5
    rng = np.random.default_rng(0)
    X = rng.uniform(-3, 3, (3, 4))
    U = np.zeros((3, 2))
    U[:, 1] = rng.uniform(-5, 5, 3)
    Fx, Fu = planning.step_jacobians(s, X, U, dt, sub)
    eps = 1e-6
    for i in range(3):
        for j in range(4):
            d = np.zeros(4)
            d[j] = eps
            fd = (s.step(X[i] + d, U[i], dt, sub) - s.step(X[i] - d, U[i], dt, sub)) / (2 * eps)
            np.testing.assert_allclose(Fx[i][:, j], fd, rtol=1e-6, atol=1e-7)
        e = np.array([0.0, eps])
        fd = (s.step(X[i], U[i] + e, dt, sub) - s.step(X[i], U[i] - e, dt, sub)) / (2 * eps)
        np.testing.assert_allclose(Fu[i][:, 1], fd, rtol=1e-6, atol=1e-7)


@pytest.mark.parametrize(
    "options, message",
    [
        ({"horizn": 3.0}, "Unknown planner option 'horizn'"),
        ({"horizon": 1e9}, "must be a number in (0.0, 3600.0]"),  # 149 GiB of steps
        ({"horizon": 3000.0}, "more than 20000 control periods"),
        ({"horizon": -1}, "horizon in the planner"),  # planned one step
        ({"max_iterations": 0}, "max_iterations in the planner"),  # planned nothing
        ({"goal_tolerance": float("nan")}, "goal_tolerance in the planner"),  # disabled the check
        ({"jacobian_substeps": 0}, "jacobian_substeps in the planner"),  # divided by zero
    ],
)
def test_bad_planner_options_are_refused_in_one_line(options, message):
    with pytest.raises(ValueError, match=re.escape(message)) as error:
        planning.plan_options(gym.make(ACROBOT), **options)
    assert "\n" not in str(error.value)


# ---- the solvable acrobot ----------------------------------------------------------------
def test_acrobot_v2_elbow_limit_is_twice_the_elbow_links_gravity_torque():
    env = gym.make(ACROBOT).unwrapped
    p = env.system.parameters
    assert env.max_input[0] == pytest.approx(2.0 * p["m2"] * p["g"] * p["l2"])  # 9.81 N*m
    assert gym.make("Lagrange/Acrobot-v1").unwrapped.max_input[0] == 3.0  # v1 unchanged


def _smallest_acceleration(env, q: np.ndarray) -> float:
    """min over the elbow torques within the limit of |qddot| at rest at q."""
    x = np.concatenate([q, [0.0, 0.0]])[None]
    a0, Bq = input_response(env.system, x, [1])
    b = Bq[0, :, 0]
    u = np.clip(-(b @ a0[0]) / (b @ b), -env.max_input[0], env.max_input[0])
    return float(np.linalg.norm(a0[0] + b * u))


def test_acrobot_v2_cannot_hold_link_one_off_the_vertical_beyond_the_mass_centre_bound():
    # Static equilibria need the mass centre on the shoulder's vertical: sin theta2 =
    # -3 sin theta1 for the default arm, so |theta1| <= asin(1/3) = 0.3398 rad (hanging or
    # inverted), at elbow torques m2 g l2 |sin theta2| <= 4.9 N*m, within the 9.81 N*m limit.
    env = gym.make(ACROBOT).unwrapped
    for base in (0.0, np.pi):
        for th1 in (0.2, 0.3):
            q = np.array([base + th1, base - np.arcsin(3 * np.sin(th1))])
            assert _smallest_acceleration(env, q) < 1e-9  # held
        for th1 in (0.36, 0.6, np.pi / 2):  # beyond the bound: no pose of link 2 holds it
            worst = min(
                _smallest_acceleration(env, np.array([base + th1, th2]))
                for th2 in np.linspace(-np.pi, np.pi, 721)
            )
            assert worst > 0.05, (base, th1, worst)


# ---- planning and tracking ---------------------------------------------------------------
@pytest.fixture(scope="module")
def acrobot_plan():
    env = gym.make(ACROBOT)
    env.reset(seed=0, options={"state": np.zeros(4)})
    return env, planning.plan(env)


@pytest.mark.slow  # plans a 4 s swing-up: about 5 s
def test_planned_swing_up_respects_the_limits_and_is_the_envs_own_motion(acrobot_plan):
    env, p = acrobot_plan
    opts = planning.plan_options(env)
    # within the limits: |action| <= action_bound (0.9 of 9.81 N*m) every period
    assert np.abs(p.actions).max() <= opts["action_bound"] + 1e-12
    # the dynamics hold to round-off: replaying the planned actions through the env's own
    # step reproduces every planned state to 1e-9 rad and rad/s
    replay = planning.rollout(env, p.x[0], p.actions)
    assert np.abs(replay - p.x).max() < 1e-9
    # and it ends inverted at rest, within the goal tolerance of 0.01 rad and rad/s
    assert p.terminal_error <= opts["goal_tolerance"]
    assert np.abs(envs.wrap(p.x[-1, :2] - np.pi)).max() <= opts["goal_tolerance"]


@pytest.mark.slow
def test_tvlqr_holds_the_plan_from_a_perturbed_start(acrobot_plan):
    # open loop the planned actions lose the arm from a 0.05 rad offset; TVLQR brings it up
    env, p = acrobot_plan
    u0 = env.unwrapped.operating_point()[1]
    tracker = tvlqr(env, p, u0)
    start = p.x[0] + np.array([0.05, -0.05, 0.05, 0.0])
    open_loop = planning.rollout(env, start, p.actions)
    assert np.abs(envs.wrap(open_loop[-1, :2] - np.pi)).max() > 0.2
    x = start
    for k in range(p.steps):
        dx = x - p.x[k]
        a = np.clip(p.actions[k] - tracker.K[k] @ dx, -1, 1)
        x = planning.env_step(env.unwrapped, x, env.unwrapped.action_to_input(a))
    assert np.abs(envs.wrap(x[:2] - np.pi)).max() < 0.05


@pytest.mark.slow  # 20 episodes of 25 s, one plan
def test_plan_agent_swings_up_and_balances_the_default_acrobot():
    stats = evaluate(ACROBOT, "plan", episodes=20, seed=0)
    assert stats.success_rate == 1.0, stats.summary()


@pytest.mark.slow
def test_plan_agent_answers_predict_for_one_observation_and_restarts_on_reset():
    env = gym.make(ACROBOT)
    policy = make_agent("plan", env)
    assert isinstance(policy, PlanPolicy)
    for seed in (0, 1):  # the second reset must start the plan again from step 0
        obs, _ = env.reset(seed=seed)
        done, success = False, False
        while not done:
            action, state = policy.predict(obs)
            assert action.shape == (1,) and state is None
            obs, _, term, trunc, info = env.step(action)
            done, success = term or trunc, info["is_success"]
        assert success


def furuta_swing_up() -> str:
    import examples.furuta_swing_up  # noqa: F401  (registers it)

    return "Examples/FurutaSwingUp-v0"


@pytest.mark.slow  # plans a 3 s swing-up of a user system: about 15 s
def test_plan_agent_swings_up_the_furuta_pendulum_of_the_examples_from_hanging():
    stats = evaluate(furuta_swing_up(), "plan", episodes=10, seed=0)
    assert stats.success_rate == 1.0, stats.summary()
