"""LQR from the exact linearisation: Jacobians, the book's (7.26), Riccati, closed loops."""

import numpy as np
import pytest

import dynamics
from agents import lqr
from agents.control import linear
from agents.control.policies import ZeroPolicy
from agents.scoring import closed_loop
from envs.tasks import acrobot
from tests.matrix import over

LQR_FAST = ("Lagrange/TwoLinkArm-v1", "Lagrange/BeadOnRod-v1")


@pytest.fixture(scope="module")
def arm():
    return dynamics.get_model("two_link_arm").compile()


@pytest.fixture(scope="module")
def disk():
    return dynamics.get_model("rolling_disk").compile()


@pytest.fixture(scope="module")
def bead():
    return dynamics.get_model("bead_on_driven_rod").compile()


def central_differences(system, x0, u0, h=1e-6):
    """d(state_derivative)/d(x, u) by central differences."""
    f = lambda x, u: system.state_derivative(0.0, x, u)  # noqa: E731
    A = np.column_stack(
        [(f(x0 + h * e, u0) - f(x0 - h * e, u0)) / (2 * h) for e in np.eye(len(x0))]
    )
    B = np.column_stack(
        [(f(x0, u0 + h * e) - f(x0, u0 - h * e)) / (2 * h) for e in np.eye(len(u0))]
    )
    return A, B


@pytest.mark.parametrize(
    "name, x0, u0",
    [
        ("arm", [0.7, -1.9, 0.8, -1.3], [2.0, -0.5]),  # far from any equilibrium
        ("arm", [np.pi, np.pi, 0.0, 0.0], [0.0, 0.0]),  # the acrobot's goal
        ("disk", [0.1, 0.2, 1.3, 0.4, 0.5, 0.0, 0.0, 0.3, 0.7, -6.0], [0.1, -0.2]),  # leaning
        (
            "disk",
            [0.0, 0.0, np.pi / 2, 0.3, 0.0, 2.4 * np.sin(0.3), 2.4 * np.cos(0.3), 0, 0, -8],
            [0, 0],
        ),
        ("bead", [0.4, 0.3, -0.2, 0.5], [0.05]),
    ],
)
def test_linearisation_matches_finite_differences(request, name, x0, u0):
    system = request.getfixturevalue(name)
    x0, u0 = np.asarray(x0, float), np.asarray(u0, float)
    A, B = system.linearize(x0, u0)
    A_fd, B_fd = central_differences(system, x0, u0)
    # central differences with h = 1e-6: truncation ~h^2 |f'''| ~1e-11, round-off
    # ~eps |f| / h ~1e-9 for |f| ~ 10; 1e-6 of the largest entry is far above both
    scale = max(np.abs(A).max(), np.abs(B).max())
    np.testing.assert_allclose(A, A_fd, atol=1e-6 * scale)
    np.testing.assert_allclose(B, B_fd, atol=1e-6 * scale)


def test_arm_linearisation_at_rest_equals_book_726(arm):
    p = arm.parameters
    I_prime = p["Ibar1"] + p["m1"] * p["l1"] ** 2 + p["m2"] * p["l"] ** 2
    I2 = p["Ibar2"] + p["m2"] * p["l2"] ** 2
    A_, B_, C_ = (
        p["m2"] * p["l"] * p["l2"],
        (p["m1"] * p["l1"] + p["m2"] * p["l"]) * p["g"],
        p["m2"] * p["g"] * p["l2"],
    )
    M = np.array([[I_prime, A_], [A_, I2]])  # (7.26): M q'' + K q = Q
    K = np.diag([B_, C_])
    Q_of_M = np.array([[1.0, -1.0], [0.0, 1.0]])  # Q1 = M1 - M2, Q2 = M2 (joint motors)
    lin = linear.linearize(arm, np.zeros(4), np.zeros(2))
    # same numbers through two routes (symbolic Jacobian vs a 2x2 solve): round-off only
    np.testing.assert_allclose(lin.A[2:, :2], -np.linalg.solve(M, K), rtol=1e-12)
    np.testing.assert_allclose(lin.A[2:, 2:], 0.0, atol=1e-12)
    np.testing.assert_allclose(lin.B[2:], np.linalg.solve(M, Q_of_M), rtol=1e-12)
    # the classical small oscillations of two uniform rods: eigenvalues +-i w, with
    # w^2 = (g/l)(3 -+ 6/sqrt 7)
    w2 = np.sort(-(np.linalg.eigvals(lin.A) ** 2).real)[::2]
    expected = p["g"] / p["l"] * np.array([3 - 6 / np.sqrt(7), 3 + 6 / np.sqrt(7)])
    np.testing.assert_allclose(w2, expected, rtol=1e-10)  # round-off of a 4x4 eig


def test_zoh_discretisation_is_the_exact_flow_of_the_linear_system(arm):
    from scipy.integrate import solve_ivp

    lin = linear.linearize(arm, [np.pi, np.pi, 0, 0], [0, 0])
    dt, x, u = 0.05, np.array([0.01, -0.02, 0.03, 0.0]), np.array([0.3, -0.1])
    Ad, Bd = linear.discretize(lin.A, lin.B, dt)
    sol = solve_ivp(lambda t, y: lin.A @ y + lin.B @ u, (0, dt), x, rtol=1e-12, atol=1e-14)
    # DOP853/RK45 at rtol 1e-12 on |x| ~ 0.05: errors ~1e-13
    np.testing.assert_allclose(Ad @ x + Bd @ u, sol.y[:, -1], atol=1e-11)


@pytest.mark.parametrize("inputs", [(0, 1), (1,)])  # both motors; the acrobot's elbow only
def test_gain_equals_python_control_dlqr(arm, inputs):
    control = pytest.importorskip("control")
    lin = linear.linearize(arm, [np.pi, np.pi, 0, 0], [0, 0])
    Ad, Bd = linear.discretize(lin.A, lin.B[:, inputs], 0.05)
    Q, R = np.diag([3.0, 1.0, 0.2, 0.1]), np.eye(len(inputs)) * 0.5
    K, P = lqr.dlqr(Ad, Bd, Q, R)
    K_ref, P_ref, _ = control.dlqr(Ad, Bd, Q, R)
    # two solvers of the same Riccati equation (both via scipy's Schur method or slycot):
    # agreement to ~1e-9 relative for cost matrices with entries up to ~1e4
    np.testing.assert_allclose(K, K_ref, rtol=1e-8, atol=1e-8 * np.abs(K_ref).max())
    np.testing.assert_allclose(P, P_ref, rtol=1e-8, atol=1e-8 * np.abs(P_ref).max())


def test_riccati_cost_is_the_closed_loop_cost(arm):
    # the value function: x0' P x0 = sum over k of x'Qx + u'Ru along the closed loop
    lin = linear.linearize(arm, [np.pi, np.pi, 0, 0], [0, 0])
    Ad, Bd = linear.discretize(lin.A, lin.B[:, 1:], 0.05)
    Q, R = np.eye(4), np.eye(1)
    K, P = lqr.dlqr(Ad, Bd, Q, R)
    x0 = x = np.array([0.02, -0.01, 0.0, 0.05])
    cost = 0.0
    for _ in range(4000):
        u = -K @ x
        cost += x @ Q @ x + u @ R @ u
        x = Ad @ x + Bd @ u
    # slowest closed-loop |z| < 0.99, so 4000 steps leave < 1e-17 of the cost; the rest is
    # round-off of a sum of 4000 terms
    assert np.abs(np.linalg.eigvals(Ad - Bd @ K)).max() < 0.99
    assert cost == pytest.approx(x0 @ P @ x0, rel=1e-9)


def test_disk_at_rest_is_uncontrollable_and_the_error_names_the_lean(disk):
    keep = ("theta", "phi", "theta_dot", "phi_dot", "psi_dot")
    at_rest = np.zeros(10)
    at_rest[2] = np.pi / 2
    lin = linear.linearize(disk, at_rest, [0, 0], keep)
    with pytest.raises(linear.UncontrollableError, match=r"rank 3 of 5.*5\.11.*theta 1\.00"):
        lqr.design(lin, 0.05, np.ones(5), np.ones(2))
    c = linear.controllability(lin.A, lin.B, lin.states)
    assert not c.controllable and c.condition == np.inf and len(c.unreachable) == 2


def test_disk_rolling_is_controllable_from_the_steering_torque_alone(disk):
    # rolling makes the lean reachable through the gyroscopic coupling of a steer
    keep = ("theta", "phi", "theta_dot", "phi_dot")
    x0 = np.zeros(10)
    x0[2], x0[6], x0[9] = np.pi / 2, 2.4, -8.0  # z' = -r psi' cos(0)
    lin = linear.linearize(disk, x0, [0, 0], keep)
    c = linear.controllability(lin.A, lin.B[:, 1:], lin.states)
    assert c.controllable and np.isfinite(c.condition)


def test_dropping_a_coupled_state_is_refused(disk):
    x0 = np.zeros(10)
    x0[2], x0[6], x0[9] = np.pi / 2, 2.4, -8.0
    with pytest.raises(ValueError, match="Cannot drop 'phi_dot': it drives 'theta_dot'"):
        linear.linearize(disk, x0, [0, 0], ("theta", "theta_dot"))
    with pytest.raises(ValueError, match="Unknown state components"):
        linear.linearize(disk, x0, [0, 0], ("theta", "lean"))


def test_bad_weights_and_periods_are_refused():
    A, B = np.array([[0.0, 1.0], [2.0, 0.0]]), np.array([[0.0], [1.0]])
    Ad, Bd = linear.discretize(A, B, 0.1)
    with pytest.raises(ValueError, match=r"Q must be \(2, 2\) or a diagonal of length 2"):
        lqr.dlqr(Ad, Bd, np.ones(3), [1.0])
    with pytest.raises(ValueError, match="R must be positive definite"):
        lqr.dlqr(Ad, Bd, np.ones(2), [0.0])
    with pytest.raises(ValueError, match="dt must be a positive"):
        linear.discretize(A, B, -0.1)
    with pytest.raises(ValueError, match=r"B must have shape \(2, m\)"):
        linear.controllability(A, np.ones((3, 1)))


# ---- closed loops on the environments ------------------------------------------------

envs = pytest.importorskip("envs")


# the bicycle's plain LQR is refused (its constraints tie pitch and yaw rate to lean and
# steer); its heuristic, the constraint-reduced LQR, is tested in test_bicycle_env.py
# the fast suite steps the arm and the bead (the disk's and the crank's closed loops take 4-5 s)
@pytest.mark.parametrize(
    "env_id", over((e for e in envs.ENV_IDS if "/Bicycle-" not in e), fast=LQR_FAST)
)
def test_lqr_brings_every_env_to_its_goal_where_zero_torque_fails(env_id):
    # 100 seeded episodes from the operating point of each drawn goal, perturbed uniformly
    # within the task's LQR region, at most 1/1.6 of the largest region with >= 99 %
    # success measured by closed_loop.largest_region (see the task's LQRHints), so the
    # issue's 99 % bar holds with a margin rather than by the luck of the seed
    lqr_run = closed_loop.evaluate_near(env_id, episodes=100, seed=0)
    assert lqr_run.success_rate >= 0.99, lqr_run.success_rate
    zero = closed_loop.evaluate_near(env_id, ZeroPolicy, episodes=100, seed=0)
    assert zero.success_rate <= 0.2, zero.success_rate  # unforced: falls / drifts away
    assert lqr_run.returns.mean() > zero.returns.mean()


def test_policy_scores_with_sb3_evaluate_policy():
    import gymnasium as gym
    from stable_baselines3.common.evaluation import evaluate_policy
    from stable_baselines3.common.monitor import Monitor

    env = Monitor(gym.make("Lagrange/TwoLinkArm-v1"))
    env.reset(seed=0)  # seeded starts: unseeded, 2 of 300 draws of 3 episodes favour zero
    policy = lqr.LQRPolicy(env)
    # the fully actuated arm from its own start distribution (any start, any goal)
    mean, _ = evaluate_policy(policy, env, n_eval_episodes=3, deterministic=True)
    zero, _ = evaluate_policy(ZeroPolicy(env), env, n_eval_episodes=3)
    assert mean > zero


def test_predict_is_batched_and_saturates():
    import gymnasium as gym

    env = gym.make("Lagrange/Acrobot-v1")
    obs, _ = env.reset(seed=0, options={"state": [np.pi + 0.3, np.pi - 0.2, 0.0, 0.0]})
    policy = lqr.LQRPolicy(env)
    one, state = policy.predict(obs)
    many, _ = policy.predict(np.stack([obs, obs, obs]))
    assert state is None and one.shape == (1,) and many.shape == (3, 1)
    np.testing.assert_array_equal(many, np.stack([one] * 3))
    assert one.dtype == np.float32 and abs(one[0]) == 1.0  # 0.3 rad is far: saturated


@pytest.mark.filterwarnings("ignore:LQR on task:RuntimeWarning")  # arbitrary points, no equilibria
@pytest.mark.parametrize("goals", ["shared", "each its own"])
def test_a_batch_acts_and_costs_as_each_row_alone(goals):
    """A batch is costed and acted on in one stacked product (one design for rows sharing
    an operating point, else one per row), with each row's own arithmetic: the same bits
    as the row alone."""
    import gymnasium as gym

    env = gym.make("Lagrange/TwoLinkArm-v1")
    policy = lqr.LQRPolicy(env)
    rng = np.random.default_rng(4)
    x0, u0 = env.unwrapped.operating_point()
    n = 9
    x = x0 + rng.normal(scale=[0.5, 0.5, 2.0, 2.0], size=(n, 4)) * rng.uniform(1e-3, 3, (n, 1))
    X0, U0 = np.tile(x0, (n, 1)), np.tile(u0, (n, 1))
    if goals == "each its own":  # other points to regulate about: a design per row
        X0[:, :2] += rng.uniform(-0.5, 0.5, (n, 2))
    alone_cost = np.array([policy.cost_to_go(x[i], X0[i], U0[i])[0] for i in range(n)])
    alone_act = np.stack([policy.act(x[i], X0[i], U0[i])[0] for i in range(n)])
    assert np.array_equal(policy.cost_to_go(x, X0, U0), alone_cost)
    assert np.array_equal(policy.act(x, X0, U0), alone_act)
    assert len(policy.designs(X0, U0)) == (1 if goals == "shared" else n)
    d, dx = policy.design(X0[0], U0[0]), policy.error(x, X0)
    assert alone_cost[0] == dx[0, d.linear.index] @ d.P @ dx[0, d.linear.index]  # as before


def test_policy_acts_on_the_goal_in_the_observation():
    import gymnasium as gym

    env = gym.make("Lagrange/TwoLinkArm-v1")
    obs, _ = env.reset(seed=3, options={"goal": [0.5, -1.0]})
    policy = lqr.LQRPolicy(env)
    x0, u0 = env.unwrapped.operating_point()
    at_goal = env.unwrapped.operating_point(obs)[0]
    np.testing.assert_allclose(at_goal, x0, atol=1e-6)  # float32 observation of the goal
    # at the goal the action is the gravity-holding torque, in action units
    a = policy.act(x0, x0, u0)[0]
    np.testing.assert_allclose(a, env.unwrapped.input_to_action(u0), rtol=1e-12)


def test_uncontrollable_env_setup_is_reported(capsys):
    import gymnasium as gym

    env = gym.make("Lagrange/RollingDisk-v1")
    env.reset(seed=0)
    policy = lqr.LQRPolicy(env)
    x0, u0 = env.unwrapped.operating_point()
    x0[[5, 6, 9]] = 0.0  # the disk standing still: the lean cannot be reached
    with pytest.raises(linear.UncontrollableError, match="theta 1.00"):
        policy.design(x0, u0)


def test_command_line_prints_the_design_and_scores(tmp_path, capsys):
    out = tmp_path / "bead.png"
    assert lqr.main(["Lagrange/BeadOnRod-v1", "--episodes", "10", "--plot", str(out)]) == 0
    text = capsys.readouterr().out
    for part in (
        "A (continuous",
        "open-loop eigenvalues",
        "controllability: rank 4 of 4",
        "gain K",
        "closed-loop |z|",
        "LQR: success 10/10",
        "zero input: success",
    ):
        assert part in text
    assert out.read_bytes()[:4] == b"\x89PNG"
    assert list(tmp_path.iterdir()) == [out]  # atomic: no temporary file left behind


def test_command_line_rejects_unknown_env(capsys):
    with pytest.raises(SystemExit):
        lqr.main(["Lagrange/Acrobat-v1"])
    assert "Did you mean 'Lagrange/Acrobot-v1'" in capsys.readouterr().err


def test_acrobot_box_region_is_bounded_by_what_any_3_nm_controller_can_recover():
    # With |a| <= 1, each unstable real mode z = w'dx of the linearisation obeys
    # z' = lam z + (w'B) a, so no controller recovers from |z| >= |w'B| / lam. The slow
    # mode (lam ~ 2.7 1/s, mostly the whole arm leaning) makes this a thin slab: the
    # task's box at the measured 1.75x lies inside it, while at 16x half the box lies
    # outside, so the acrobot's small box is the 3 N*m limit, not the LQR weights.
    import gymnasium as gym

    env = gym.make("Lagrange/Acrobot-v1")
    env.reset(seed=0)
    d = lqr.LQRPolicy(env).design()
    lam, W = np.linalg.eig(d.linear.A.T)
    unstable = [k for k in range(len(lam)) if lam[k].real > 0]
    assert len(unstable) == 2 and np.allclose(lam[unstable].imag, 0)
    half = np.array([acrobot.TASK.lqr.region[s] for s in d.linear.states])
    rng = np.random.default_rng(0)
    for scale, inside in ((1.75, 1.0), (16.0, 0.6)):
        dx = rng.uniform(-1, 1, (20000, 4)) * scale * half
        ok = np.ones(len(dx), dtype=bool)
        for k in unstable:
            w = W[:, k].real
            ok &= np.abs(dx @ w) < np.abs(w @ d.linear.B[:, 0]) / lam[k].real
        # 1.75x: every sample inside (measured 100 %); 16x: measured 48 % inside, so any
        # controller is below 60 % there (20000 samples: sampling error ~0.4 %)
        assert (ok.mean() == 1.0) if inside == 1.0 else (ok.mean() < inside)
