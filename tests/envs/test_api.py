"""The Gymnasium contract of every registered Lagrange environment."""

from __future__ import annotations

import copy
import os
import pickle
import warnings

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import envs
from envs import rendering
from examples import cart_pole, double_cart_pole, furuta  # noqa: F401  (registers them)
from tests.matrix import over

# the built-ins, the 3 N*m acrobot they replaced, and systems beyond the book (examples/):
# every env, a user's too, keeps the same contract
IDS = list(envs.ENV_IDS) + [
    "Lagrange/Acrobot-v1",
    "Examples/CartPole-v0",
    "Examples/Furuta-v0",
    "Examples/DoubleCartPole-v0",
]


def rollout(env, seed: int, steps: int, action_seed: int = 0):
    """Observations, rewards and states of `steps` random actions after reset(seed)."""
    rng = np.random.default_rng(action_seed)
    obs, _ = env.reset(seed=seed)
    out = [(obs, 0.0, env.unwrapped.state)]
    for _ in range(steps):
        a = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        obs, r, term, trunc, info = env.step(a)
        out.append((obs, r, info["state"]))
        if term or trunc:
            break
    return out


def test_ids_are_registered_with_limits_and_vector_entry_points():
    assert list(envs.ENV_IDS) == [
        "Lagrange/TwoLinkArm-v1",
        "Lagrange/Acrobot-v2",
        "Lagrange/RollingDisk-v1",
        "Lagrange/BeadOnRod-v1",
        "Lagrange/CrankSlider-v1",
        "Lagrange/Bicycle-v0",
    ]
    for env_id in IDS:
        spec = gym.spec(env_id)
        assert spec.max_episode_steps > 0
        assert spec.vector_entry_point is not None


@pytest.mark.parametrize("env_id", over(IDS))
def test_gymnasium_checker(env_id):
    env = gym.make(env_id, render_mode="rgb_array").unwrapped
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # any checker warning is a failure
        check_env(env, skip_render_check=False)


@pytest.mark.parametrize("env_id", over(IDS))
def test_stable_baselines3_checker(env_id):
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = gym.make(env_id).unwrapped  # (an older version's id warns that it is older)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sb3_checker.check_env(env)


@pytest.mark.parametrize("env_id", over(IDS))
def test_same_seed_same_trajectory_bit_for_bit(env_id):
    a = rollout(gym.make(env_id), seed=3, steps=50)
    b = rollout(gym.make(env_id), seed=3, steps=50)
    assert len(a) == len(b)
    for (oa, ra, xa), (ob, rb, xb) in zip(a, b):
        assert np.array_equal(oa, ob) and ra == rb and np.array_equal(xa, xb)
    c = rollout(gym.make(env_id), seed=4, steps=1)
    assert not np.array_equal(a[0][2], c[0][2])


@pytest.mark.parametrize("env_id", over(IDS))
@pytest.mark.parametrize("clone", [pickle.loads, copy.deepcopy], ids=["pickle", "deepcopy"])
def test_pickle_and_deepcopy_continue_the_same_trajectory(env_id, clone):
    env = gym.make(env_id, render_mode="rgb_array")
    env.reset(seed=1)
    env.render()  # a live pygame surface must not stop a copy
    env.step(env.action_space.sample())
    twin = clone(pickle.dumps(env)) if clone is pickle.loads else clone(env)
    a = np.full(env.action_space.shape, 0.3, np.float32)
    for _ in range(5):
        o1, r1, *_ = env.step(a)
        o2, r2, *_ = twin.step(a)
        assert np.array_equal(o1, o2) and r1 == r2
    assert twin.render().shape == (rendering.SIZE, rendering.SIZE, 3)


@pytest.mark.parametrize("env_id", over(IDS))
def test_vector_env_reproduces_single_envs(env_id):
    n, steps = 3, 40
    vec = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point")
    singles = [gym.make(env_id) for _ in range(n)]
    obs, _ = vec.reset(seed=10)
    for i, env in enumerate(singles):
        o, _ = env.reset(seed=10 + i)
        assert np.array_equal(obs[i], o)
    rng = np.random.default_rng(0)
    for _ in range(steps):
        actions = rng.uniform(-1.2, 1.2, vec.action_space.shape).astype(np.float32)
        obs, rew, term, trunc, info = vec.step(actions)
        for i, env in enumerate(singles):
            o, r, te, tr, inf = env.step(actions[i])
            # the same compiled kernels on the same numbers: exact equality
            assert np.array_equal(info["state"][i], inf["state"])
            assert np.array_equal(obs[i], o) and rew[i] == r
            assert (term[i], trunc[i]) == (te, tr)
            if te or tr:  # the vector env resets it on its next step: stop comparing
                singles[i] = None
        singles = [s for s in singles if s is not None] if None in singles else singles
        if len(singles) < n:
            break


def test_vector_env_autoresets_on_the_next_step():
    vec = gym.make_vec(
        "Lagrange/TwoLinkArm-v1",
        num_envs=2,
        vectorization_mode="vector_entry_point",
        max_episode_steps=3,
    )
    assert vec.metadata["autoreset_mode"] == gym.vector.AutoresetMode.NEXT_STEP
    vec.reset(seed=0)
    zero = np.zeros((2, 2), np.float32)
    for _ in range(2):
        _, _, _, trunc, _ = vec.step(zero)
        assert not trunc.any()
    _, _, _, trunc, info = vec.step(zero)
    assert trunc.all()
    final = info["state"].copy()
    obs, rew, term, trunc, info = vec.step(zero)  # the reset step: reward 0, fresh state
    assert not (term | trunc).any() and (rew == 0).all()
    assert not np.allclose(info["state"], final)
    rates = vec.unwrapped.state_from_observation(obs)[:, 2:]
    np.testing.assert_allclose(rates, info["state"][:, 2:], rtol=1e-6)  # float32 observation


@pytest.mark.parametrize("env_id", over(IDS))
def test_random_actions_stay_finite_for_ten_thousand_steps(env_id):
    vec = gym.make_vec(env_id, num_envs=100, vectorization_mode="vector_entry_point")
    obs, _ = vec.reset(seed=0)
    rng = np.random.default_rng(1)
    space = vec.single_observation_space
    for _ in range(100):  # 100 copies x 100 steps
        actions = rng.uniform(-1, 1, vec.action_space.shape)
        obs, rew, term, trunc, info = vec.step(actions)
        assert np.isfinite(obs).all() and np.isfinite(rew).all()
        assert np.isfinite(info["energy"]).all()
        assert ((obs >= space.low) & (obs <= space.high)).all()


@pytest.mark.parametrize("env_id", over(IDS))
def test_rendering_returns_frames_of_the_documented_shape(env_id):
    env = gym.make(env_id, render_mode="rgb_array")
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (rendering.SIZE, rendering.SIZE, 3) and frame.dtype == np.uint8
    assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 3  # something is drawn
    env.step(np.ones(env.action_space.shape, np.float32))  # full input: it visibly moves
    assert not np.array_equal(env.render(), frame) or env_id.endswith("BeadOnRod-v1")
    env.close()
    human = gym.make(env_id, render_mode="human")
    human.reset(seed=0)
    assert human.render() is None
    human.close()
    vec = gym.make_vec(env_id, 2, vectorization_mode="vector_entry_point", render_mode="rgb_array")
    vec.reset(seed=0)
    frames = vec.render()
    assert len(frames) == 2 and frames[0].shape == frame.shape
    assert gym.make(env_id).metadata["render_fps"] == round(
        1 / gym.make(env_id).unwrapped.control_period
    )


@pytest.mark.parametrize("env_id", over(IDS))
def test_bad_actions_are_refused(env_id):
    env = gym.make(env_id).unwrapped
    with pytest.raises(RuntimeError, match="reset"):
        env.step(env.action_space.sample())
    env.reset(seed=0)
    n = env.action_space.shape[0]
    for bad in (np.nan, np.inf, -np.inf):
        with pytest.raises(ValueError, match="NaN or inf"):
            env.step(np.full(n, bad))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(n + 1))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros((1, n)))
    with pytest.raises(TypeError, match="action must be numeric"):
        env.step("left")
    with pytest.raises(TypeError, match="action must be real"):
        env.step(np.full(n, 0.5 + 7j))
    x = env.state
    # both from a reset to x: a given state's rates are projected onto the constraints,
    # which may move them by round-off
    env.reset(options={"state": x})
    env.step(np.full(n, 5.0))  # clipped, as documented: the same as the limit
    y = env.state
    env.reset(options={"state": x})
    env.step(np.ones(n))
    assert np.array_equal(env.state, y)
    vec = gym.make_vec(env_id, 2, vectorization_mode="vector_entry_point")
    vec.reset(seed=0)
    with pytest.raises(ValueError, match=r"envs \[1\]"):
        vec.step(np.array([np.zeros(n), np.full(n, np.nan)]))


@pytest.mark.parametrize("env_id", over(IDS))
def test_bad_keyword_arguments_name_the_problem(env_id):
    env = gym.make(env_id).unwrapped
    name = next(iter(env.system.parameters))
    with pytest.raises(ValueError, match=f"Did you mean '{name}'"):
        gym.make(env_id, **{name + "x": 1.0})
    with pytest.raises(ValueError, match="Did you mean 'control_period'"):
        gym.make(env_id, control_perid=0.1)
    with pytest.raises(ValueError, match="positive"):
        gym.make(env_id, **{name: -1.0})
    with pytest.raises(ValueError, match="control_period"):
        gym.make(env_id, control_period=0.0)
    with pytest.raises(TypeError, match="substeps"):
        gym.make(env_id, substeps=2.5)
    with pytest.raises(ValueError, match="max_input"):
        gym.make(env_id, max_input=-1.0)
    with pytest.raises(ValueError, match="render_mode"), pytest.warns(UserWarning):
        gym.make(env_id, render_mode="ascii")  # gymnasium warns first, then the env refuses
    with pytest.raises(ValueError, match="reset option"):
        env.reset(options={"sate": env.state})
    with pytest.raises(ValueError, match="options\\['state'\\]"):
        env.reset(options={"state": np.zeros(3)})


@pytest.mark.parametrize("env_id", over(IDS))
def test_keyword_arguments_reach_the_model(env_id):
    env = gym.make(env_id, control_period=0.02, substeps=3, max_input=0.5).unwrapped
    assert env.control_period == 0.02 and env.substeps == 3
    assert np.all(env.max_input == 0.5)
    name, value = next(iter(env.system.parameters.items()))
    assert gym.make(env_id, **{name: 2 * value}).unwrapped.system.parameters[name] == 2 * value


@pytest.mark.parametrize("env_id", over(IDS))
def test_contract_attributes(env_id):
    env = gym.make(env_id).unwrapped
    obs, info = env.reset(seed=2)
    s = env.system
    assert env.state.dtype == np.float64 and env.state.shape == (s.state_size,)
    assert len(env.periodic) == s.n_q
    assert env.max_input.shape == env.action_space.shape
    # action <-> input, batched over leading axes
    actions = np.random.default_rng(0).uniform(-1, 1, (4, 3) + env.action_space.shape)
    u = env.action_to_input(actions)
    assert u.shape == (4, 3, s.n_u)
    np.testing.assert_allclose(env.input_to_action(u), actions, rtol=1e-15)
    assert np.all(
        np.abs(env.action_to_input(10 * actions))
        <= np.abs(env.action_to_input(np.sign(actions))) + 0
    )
    # the observation encodes the observed state and the goal
    x = env.state_from_observation(obs)
    observed = np.array([c not in env.plant.unobserved for c in s.coordinates])
    assert observed.any()
    periodic = np.array(env.periodic)
    err = x[: s.n_q] - env.state[: s.n_q]
    err = np.where(periodic, (err + np.pi) % (2 * np.pi) - np.pi, err)
    # float32 observations: 1e-6 relative, a few 1e-7 rad through atan2
    np.testing.assert_allclose(err[observed], 0, atol=1e-5)
    np.testing.assert_allclose(x[s.n_q :], env.state[s.n_q :], rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(env.goal_from_observation(obs), env.goal, rtol=1e-6, atol=1e-6)
    batch = np.stack([obs, obs])
    assert env.state_from_observation(batch).shape == (2, s.state_size)
    # the operating point: a motion the model keeps with the input u0 (zero accelerations)
    x0, u0 = env.operating_point()
    np.testing.assert_allclose(s.accelerations(0.0, x0, u0), 0, atol=1e-9)  # round-off
    assert np.all(np.abs(env.input_to_action(u0)) <= 1)  # holdable within the limits
    X0, U0 = env.operating_point(batch)
    assert X0.shape == (2, s.state_size) and U0.shape == (2, s.n_u)
    np.testing.assert_allclose(X0[0], x0, atol=1e-6)  # float32 goal in obs
    keys = {"state", "input", "energy", "reward_terms", "is_success", "diverged"}
    _, r, _, _, info = env.step(env.action_space.sample())
    assert keys <= set(info)
    assert r == pytest.approx(sum(info["reward_terms"].values()), abs=1e-12)
    assert ("constraint_residual" in info) == (s.n_c > 0)


def test_diverging_simulation_terminates_with_finite_observation():
    env = gym.make("Lagrange/TwoLinkArm-v1", control_period=2.0, substeps=1)
    env.reset(seed=0, options={"state": [1.0, 2.0, 20.0, -20.0]})
    for _ in range(10):
        obs, r, term, trunc, info = env.step(np.ones(2, np.float32))
        assert np.isfinite(obs).all() and np.isfinite(r)
        assert env.observation_space.contains(obs)
        if term:
            break
    assert term and not trunc and info["diverged"]


@pytest.mark.slow  # two new processes: ~2.8 s
def test_rendering_without_a_display_is_quiet_for_arrays_and_says_so_for_windows():
    import subprocess
    import sys

    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        pytest.skip("a display is available")
    env = {k: v for k, v in os.environ.items() if k != "SDL_VIDEODRIVER"}

    def run(mode: str) -> subprocess.CompletedProcess:
        code = (
            "import gymnasium as gym, envs\n"
            f"e = gym.make('Lagrange/BeadOnRod-v1', render_mode={mode!r}); e.reset(seed=0)\n"
            "print(None if e.render() is None else e.render().shape)\n"
        )
        return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)

    arrays = run("rgb_array")
    assert arrays.returncode == 0 and arrays.stdout.strip() == "(500, 500, 3)"
    assert arrays.stderr == ""  # no display opened, nothing printed
    window = run("human")
    assert window.returncode == 0 and "found no display" in window.stderr


def test_a_declared_operating_point_is_solved_once_per_goal(monkeypatch):
    """The arm's operating point is the goal (a dict): agents ask for it at every step, and
    each distinct goal is solved once, with the same numbers as solving it again."""
    from envs.plant import Plant

    env = gym.make("Lagrange/TwoLinkArm-v1").unwrapped
    obs = np.stack([env.reset(seed=s)[0] for s in range(3)])
    batch = obs[[0, 1, 0, 2, 1]]
    expected = env.plant.operating_point(env.goal_from_observation(batch),
                                         env.state_from_observation(batch))  # fmt: skip
    solved = []
    solve = Plant.operating_point
    monkeypatch.setattr(
        Plant, "operating_point", lambda p, g, x: solved.append(1) or solve(p, g, x)
    )
    for _ in range(2):
        X0, U0 = env.operating_point(batch)
        assert np.array_equal(X0, expected[0]) and np.array_equal(U0, expected[1])
    assert len(solved) == 3  # three goals
