"""The task declaration and the batched runtime: inverse maps, single vs vector env in both
autoreset modes, ending early never paying, envs from any kind of model, bad declarations."""

from __future__ import annotations

import dataclasses
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import dynamics
import envs
from dynamics import stepping
from envs.plant import Plant
from envs.tasks import arm
from examples import cart_pole, double_cart_pole, furuta  # noqa: F401  (registers them)
from tests.matrix import over

IDS = list(envs.ENV_IDS) + [
    "Examples/CartPole-v0",
    "Examples/Furuta-v0",
    "Examples/DoubleCartPole-v0",
]


def task_of(env_id):
    return gym.spec(env_id).kwargs["task"]


@pytest.mark.parametrize("env_id", over(IDS))
def test_observation_inverse_maps_round_trip(env_id):
    env = gym.make(env_id).unwrapped
    plant, rng = env.plant, np.random.default_rng(0)
    for _ in range(20):
        env.reset(seed=int(rng.integers(1 << 30)))
        x, g = env.state, env.goal
        obs = env.unwrapped._rt.O[0].astype(np.float64)
        # the float64 observation before rounding to float32 inverts exactly (round-off)
        obs64 = env.unwrapped._rt.arrays.obs64[0]
        back = plant.state_from_observation(obs64[None])[0]
        angles, values, _ = plant.observation.state_map
        seen = [i for i, *_ in angles] + [i for i, _ in values]
        err = back[seen] - x[seen]
        angle = np.isin(seen, np.flatnonzero(plant.periodic))
        err[angle] = dynamics.wrap(err[angle])
        np.testing.assert_allclose(err, 0, atol=1e-12)
        np.testing.assert_allclose(
            dynamics.wrap(plant.goal_from_observation(obs64[None])[0] - g), 0, atol=1e-12
        )
        # and the float32 observation to float32 precision
        np.testing.assert_allclose(dynamics.wrap(env.goal_from_observation(obs) - g), 0, atol=1e-5)


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
@pytest.mark.parametrize("env_id", over(IDS))
def test_vector_env_equals_single_envs_bit_for_bit_across_episodes(env_id, mode):
    n, limit = 3, 7  # short episodes: every copy crosses several episode boundaries
    vec = gym.make_vec(
        env_id, n, vectorization_mode="vector_entry_point", max_episode_steps=limit,
        autoreset_mode=mode,
    )  # fmt: skip
    singles = [gym.make(env_id, max_episode_steps=limit) for _ in range(n)]
    obs, _ = vec.reset(seed=5)
    for i, env in enumerate(singles):
        assert np.array_equal(env.reset(seed=5 + i)[0], obs[i])
    rng = np.random.default_rng(1)
    pending = np.zeros(n, dtype=bool)  # NEXT_STEP: reset by the vector env's next step
    ended = 0
    for _ in range(30):
        a = rng.uniform(-1.5, 1.5, vec.action_space.shape).astype(np.float32)
        obs, rew, term, trunc, info = vec.step(a)
        for i, env in enumerate(singles):
            if pending[i]:
                o, _ = env.reset()
                assert np.array_equal(obs[i], o) and rew[i] == 0 and not (term[i] or trunc[i])
                continue
            o, r, te, tr, inf = env.step(a[i])
            assert rew[i] == r and (term[i], trunc[i]) == (te, tr)
            same_step_end = (te or tr) and mode == AutoresetMode.SAME_STEP
            state = info["final_info"]["state"] if same_step_end else info["state"]
            assert np.array_equal(state[i], inf["state"])
            if te or tr:
                ended += 1
                if mode == AutoresetMode.SAME_STEP:
                    assert np.array_equal(info["final_obs"][i], o)
                    assert np.array_equal(obs[i], env.reset()[0])
            else:
                assert np.array_equal(obs[i], o)
        pending = (term | trunc) & ~pending if mode == AutoresetMode.NEXT_STEP else pending
    assert ended >= n  # the comparison crossed episode ends


@pytest.mark.parametrize("env_id", over(IDS))
def test_ending_early_never_pays(env_id):
    """Every step pays at least the sum of the terms' lower bounds, r_min (the runtime clips
    each term into its declared bounds); a step that ends the episode early adds (steps left)
    x min(0, r_min). So ending at step k returns at most what any continuation would have:
    the continuation pays at least (steps left) x r_min."""
    limit = gym.spec(env_id).max_episode_steps
    # bang-bang actions held for 0.5 s (the next test makes every task diverge)
    vec = gym.make_vec(env_id, 64, vectorization_mode="vector_entry_point", control_period=0.5)
    plant = vec.unwrapped.plant
    lowest = plant.lowest_reward
    vec.reset(seed=0)
    rng = np.random.default_rng(0)
    names = [t.name for t in plant.task.terms]
    steps = np.zeros(64, dtype=int)
    for _ in range(60):
        a = rng.choice([-1.0, 1.0], vec.action_space.shape)
        _, rew, term, trunc, info = vec.step(a)
        steps += 1
        stepped = steps > 0  # the others were reset by this step (reward 0)
        terms = np.stack([info["reward_terms"][k] for k in names], axis=1)[stepped]
        assert ((terms >= plant.term_low) & (terms <= plant.term_high)).all()
        penalty = np.where(term, (limit - steps) * min(0.0, lowest), 0.0)[stepped]
        np.testing.assert_allclose(
            rew[stepped], terms.sum(axis=1) + penalty, rtol=1e-12, atol=1e-12
        )
        assert (rew[~stepped] == 0).all()
        assert not (term & trunc).any()  # divergence terminates, it does not truncate
        assert (term[info["diverged"]]).all()
        steps[term | trunc] = -1  # the next step resets them (reward 0, counted from 0)


@pytest.mark.parametrize("env_id", over(IDS))
def test_ending_early_never_pays_when_the_integration_diverges(env_id):
    # one RK4 step of 2 s per control period: the integration itself diverges, so the
    # property above is exercised on every task, not vacuously
    vec = gym.make_vec(
        env_id, 32, vectorization_mode="vector_entry_point", control_period=2.0, substeps=1
    )
    limit, lowest = gym.spec(env_id).max_episode_steps, vec.unwrapped.plant.lowest_reward
    vec.reset(seed=0)
    _, rew, term, trunc, info = vec.step(np.ones(vec.action_space.shape))
    for _ in range(10):
        if term.any():
            break
        _, rew, term, trunc, info = vec.step(np.ones(vec.action_space.shape))
    assert term.any() and not trunc[term].any()
    terms = sum(info["reward_terms"][t.name][term] for t in vec.unwrapped.task.terms)
    steps = vec.unwrapped._rt.steps[term]
    np.testing.assert_allclose(rew[term], terms + (limit - steps) * min(0.0, lowest), rtol=1e-12)


# ---- envs from any kind of model ---------------------------------------------------------
def _task_on(model):
    return envs.Task(**{**arm.TASK.__dict__, "model": model})


# each form compiles its model's kernels (1-2 s): the fast suite builds the factory's
@pytest.mark.parametrize(
    "kind",
    [pytest.param(k, marks=pytest.mark.slow) for k in ("name", "Model", "System")] + ["factory"],
)
def test_env_from_a_name_a_model_a_factory_or_a_system(kind):
    from dynamics.models.arm import two_link_arm

    model = {
        "name": "two_link_arm",
        "Model": dynamics.Model(two_link_arm),
        "factory": two_link_arm,
        "System": dynamics.get_model("two_link_arm").compile(),
    }[kind]
    env = envs.LagrangianEnv(_task_on(model))
    ref = gym.make("Lagrange/TwoLinkArm-v1").unwrapped
    assert np.array_equal(env.reset(seed=3)[0], ref.reset(seed=3)[0])
    a = np.array([0.3, -0.2], np.float32)
    for _ in range(5):  # the same derived equations: the same numbers
        (o1, r1, *_), (o2, r2, *_) = env.step(a), ref.step(a)
        assert np.array_equal(o1, o2) and r1 == r2


def test_a_user_task_registers_with_one_call_and_runs_through_make_vec():
    env_id = "TestNS/ArmAgain-v0"
    envs.register(env_id, arm.TASK)
    assert gym.spec(env_id).max_episode_steps == arm.TASK.max_episode_steps
    vec = gym.make_vec(env_id, 4, vectorization_mode="vector_entry_point")
    obs, _ = vec.reset(seed=0)
    assert obs.shape == (4, 14)


# ---- task functions numba cannot compile still work -------------------------------------
def _squared_error(x, goal):  # a plain Python helper: numba cannot call it from compiled code
    e1 = dynamics.wrap(x.theta1 - goal.theta1_star)
    e2 = dynamics.wrap(x.theta2 - goal.theta2_star)
    return e1 * e1 + e2 * e2


def _python_only(x, a, goal, p):
    return -_squared_error(x, goal)


def _zero(x, a, goal, p):
    return 0.0 * x.theta1


def with_first_term(task, fn):
    """`task` with its first reward term given by `fn` and the others 0."""
    first, *rest = task.terms
    terms = (dataclasses.replace(first, fn=fn), *(dataclasses.replace(t, fn=_zero) for t in rest))
    return dataclasses.replace(task, terms=terms)


def test_a_task_function_numba_cannot_type_runs_as_python_with_a_warning():
    task = with_first_term(arm.TASK, _python_only)
    with pytest.warns(RuntimeWarning, match="plain Python"):
        env = envs.LagrangianEnv(task)
    env.reset(seed=0)
    _, r, *_ = env.step(np.zeros(2, np.float32))
    e = dynamics.wrap(env.state[:2] - env.goal)
    assert r == pytest.approx(-(e @ e), rel=1e-12)


# ---- bad declarations and bad resets name the problem -----------------------------------
@pytest.mark.parametrize(
    "change, message",
    [
        ({"observation": (envs.Angle("theta3"),)}, "Did you mean 'theta2'"),
        ({"observation": (envs.Value("theta1"),)}, "needs a finite bound"),
        ({"actuated": ("M3", "M2")}, "actuates 'M3'"),
        ({"limits": {"theta_1": 1.0}}, "unknown state component 'theta_1'"),
        ({"max_input": (1.0,)}, "needs one limit per actuated input"),
        ({"model": 42}, "model must be"),
    ],
)
def test_bad_task_declarations_name_the_problem(change, message):
    with pytest.raises((ValueError, TypeError), match=message):
        envs.LagrangianEnv(envs.Task(**{**arm.TASK.__dict__, **change}))


def test_resets_refuse_what_the_task_cannot_take():
    env = gym.make("Lagrange/TwoLinkArm-v1").unwrapped
    with pytest.raises(ValueError, match="theta1_dot.*beyond the task's limit"):
        env.reset(options={"state": [0, 0, 100.0, 0]})
    with pytest.raises(ValueError, match=r"shape \(2,\)"):
        env.reset(options={"goal": np.zeros((3, 2))})  # a batch of goals for one env
    with pytest.raises(TypeError, match="real"):
        env.reset(options={"state": np.array([0, 0, 1j, 0])})
    vec = gym.make_vec("Lagrange/TwoLinkArm-v1", 2, vectorization_mode="vector_entry_point")
    with pytest.raises(ValueError, match=r"\(2, 2\)"):
        vec.reset(options={"goal": np.zeros((3, 2))})  # N + 1 goal rows
    obs, _ = vec.reset(options={"goal": np.array([[0.5, 1.0], [1.5, -1.0]])})
    np.testing.assert_allclose(vec.unwrapped.goal, [[0.5, 1.0], [1.5, -1.0]])


@pytest.mark.slow  # docs: builds every env's plant (the bicycle's alone compiles for it)
def test_docstring_tables_are_current():
    from envs.docs import MODULES, regenerated

    stale = [m for m in MODULES if (lambda r: r[1] != r[2])(regenerated(m))]
    assert not stale, f"run `python -m envs.docs`: stale tables in {stale}"


def test_the_plant_gives_the_observation_table_of_the_docstring():
    plant = Plant.build(arm.TASK)
    labels = [c[0] for c in plant.columns]
    assert labels[:4] == ["cos theta1", "sin theta1", "cos theta2", "sin theta2"]
    assert "| 13 | sin(theta2 - theta2*) | -1 | 1 |  |" in arm.__doc__
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert plant.obs_size == 14


@pytest.mark.parametrize(
    ("env_id", "kwargs"),
    [("Lagrange/RollingDisk-v1", {}), ("Lagrange/TwoLinkArm-v1", {"randomize": {}})],
)
def test_rows_stepped_one_at_a_time_before_the_fused_step_step_as_the_lanes(
    env_id, kwargs, monkeypatch
):
    """A new vector env's rows step one at a time (`erk_row`) until its fused step is bound,
    so that an env stepped a few times never compiles the lanes: the same results bit for
    bit (the disk: projected; the arm: each copy's own parameters)."""
    runs = []
    for one_by_one in (True, False):
        vec = gym.make_vec(env_id, 9, vectorization_mode="vector_entry_point", **kwargs)
        rt = vec.unwrapped._rt
        rt.stepper.separate(one_by_one)  # the step of separate calls
        if one_by_one:  # the lanes are never called
            monkeypatch.setattr(stepping, "erk_rows", lambda *a, **k: pytest.fail("lanes"))
        rng = np.random.default_rng(5)
        out = [vec.reset(seed=5)[0]]
        for _ in range(30):
            a = rng.uniform(-1, 1, vec.action_space.shape).astype(np.float32)
            out += vec.step(a)[:4]
        monkeypatch.undo()
        runs.append(out)
    for x, y in zip(*runs):
        assert np.array_equal(x, y)
