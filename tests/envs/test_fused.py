"""The fused step (envs/fused.py): the same numbers as the step of separate calls, and a
fingerprint that changes with anything the task's functions reach (numba's disk cache
does not look past the function it caches)."""

from __future__ import annotations

import importlib.util
import re
import sys

import gymnasium as gym
import numpy as np
import pytest
from numba import njit

import envs
from envs import buffers
from envs.fused import fingerprint
from envs.tasks import arm
from examples import cart_pole, double_cart_pole, furuta  # noqa: F401  (registers them)
from tests.binding import bound
from tests.envs.test_runtime import with_first_term
from tests.matrix import over

IDS = list(envs.ENV_IDS) + [
    "Examples/CartPole-v0",
    "Examples/Furuta-v0",
    "Examples/DoubleCartPole-v0",
]


def _pair(env_id, n, **kwargs):
    fused, separate = (
        gym.make_vec(env_id, n, vectorization_mode="vector_entry_point", **kwargs) for _ in range(2)
    )
    bound(fused)
    separate.unwrapped._rt.stepper.separate()  # the step of separate calls
    return fused, separate


@pytest.mark.parametrize("env_id", over(IDS))
def test_the_fused_step_equals_the_separate_calls_bit_for_bit(env_id):
    fused, separate = _pair(env_id, 3, max_episode_steps=7)  # crosses episode ends
    o1, _ = fused.reset(seed=5)
    o2, _ = separate.reset(seed=5)
    rng = np.random.default_rng(0)
    for _ in range(25):
        a = rng.uniform(-1.5, 1.5, fused.action_space.shape).astype(np.float32)  # clipped
        s1, s2 = fused.step(a), separate.step(a)
        for v1, v2 in zip(s1[:4], s2[:4]):
            assert np.array_equal(v1, v2)
        for k in ("state", "is_success", "diverged"):
            assert np.array_equal(s1[4][k], s2[4][k])
        for k, v in s1[4]["reward_terms"].items():
            assert np.array_equal(v, s2[4]["reward_terms"][k])


def test_the_fused_step_ends_a_diverging_row_like_the_separate_calls():
    # one 2 s step at full torque leaves the arm's rate limit behind: divergence ends it
    fused, separate = _pair("Lagrange/TwoLinkArm-v1", 2, control_period=2.0, substeps=2)
    fused.reset(seed=0)
    separate.reset(seed=0)
    a = np.array([[1.0, 1.0], [0.0, 0.0]], np.float32)
    s1, s2 = fused.step(a), separate.step(a)
    assert s1[4]["diverged"][0] and s1[2][0]
    for v1, v2 in zip(s1[:4], s2[:4]):
        assert np.array_equal(v1, v2)
    assert np.array_equal(fused.unwrapped.state, separate.unwrapped.state)
    assert np.isfinite(fused.unwrapped.state).all()


def test_the_fused_step_takes_any_action_dtype_and_refuses_nan():
    env = gym.make("Lagrange/BeadOnRod-v1").unwrapped
    env.reset(seed=0)
    for a in (np.zeros(1, np.float32), np.zeros(1), np.zeros(1, np.int64), [0.5]):
        env.step(a)
    readonly = np.zeros(1)
    readonly.setflags(write=False)
    env.step(readonly)
    before = env.state
    with pytest.raises(ValueError, match="NaN or inf"):
        env.step(np.array([np.nan]))
    assert np.array_equal(env.state, before)  # nothing changed


def test_many_threads_over_many_rows_keep_the_separate_calls():
    vec = gym.make_vec(
        "Lagrange/TwoLinkArm-v1", 130, vectorization_mode="vector_entry_point", num_threads=2
    )
    assert vec.unwrapped._rt.stepper.fused is None  # blocks spread over threads
    one = bound(
        gym.make_vec("Lagrange/TwoLinkArm-v1", 130, vectorization_mode="vector_entry_point")
    )
    a = np.full((130, 2), 0.3, np.float32)
    vec.reset(seed=1)
    one.reset(seed=1)
    for _ in range(3):
        assert np.array_equal(vec.step(a)[0], one.step(a)[0])


# ---- the fingerprint -----------------------------------------------------------------------
HELPER = """
import numpy as np
from numba import njit

SCALE = {scale}


@njit(cache=False)
def helper(x):
    return {body}


def reward(x, a, g, p):
    return (-SCALE * helper(x[:, 0]),)
"""


def _module(tmp_path, name, scale=1.0, body="x * x"):
    path = tmp_path / f"{name}.py"
    path.write_text(HELPER.format(scale=scale, body=body))
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def test_the_fingerprint_follows_constants_and_helpers_the_function_reaches(tmp_path):
    base = fingerprint(_module(tmp_path, "fp_a").reward)
    assert base is not None
    assert fingerprint(_module(tmp_path, "fp_a").reward) == base  # reloaded: unchanged
    assert fingerprint(_module(tmp_path, "fp_a", scale=2.0).reward) != base  # a constant
    assert fingerprint(_module(tmp_path, "fp_a", body="x * x * x").reward) != base  # a helper


_OPAQUE = object()


def _reaches_an_opaque_object(x, a, g, p):
    return _OPAQUE


def test_a_function_reaching_an_opaque_object_has_no_fingerprint():
    assert fingerprint(_reaches_an_opaque_object) is None
    assert fingerprint(arm.angle, arm.success) is not None


def _closure_reward(weight):
    def reward(x, a, goal, p):
        return -weight * x.theta1**2

    return reward


def test_closures_are_fingerprinted_by_their_cells():
    assert fingerprint(_closure_reward(1.0)) == fingerprint(_closure_reward(1.0))
    assert fingerprint(_closure_reward(1.0)) != fingerprint(_closure_reward(2.0))
    # and the runtime compiles each into its own fused step
    task = with_first_term(arm.TASK, _closure_reward(3.0))
    env = envs.LagrangianEnv(task)
    env.reset(seed=0)
    _, r, *_ = env.step(np.zeros(2, np.float32))
    assert env._rt.stepper.fused is not None
    assert r == pytest.approx(-3.0 * env.state[0] ** 2 + 0.0, rel=1e-12)


@pytest.mark.parametrize(
    "value", [np.arange(3.0) - 0.5, np.arange(3), np.asarray(7.25), 2.5, 3], ids=str
)
def test_the_fused_steps_column_writes_equal_numpys_assignment(value):
    """The generated step writes a task function's result with row loops (`put_column`,
    `put_rows`): the same values as numpy's broadcasting assignment, for one value per row
    (float or int), one value for all (a scalar or a 0-d array)."""
    from numba import njit

    from envs.buffers import put_column, put_rows

    @njit
    def write(out, flags, v, w):
        put_column(out, 1, v)
        put_rows(flags, w)

    out, expected = np.zeros((3, 2)), np.zeros((3, 2))
    flags = np.zeros(3, dtype=bool)
    write(out, flags, value, np.array([True, False, True]))
    expected[:, 1] = value
    assert np.array_equal(out, expected)
    assert flags.tolist() == [True, False, True]


def test_the_generated_step_names_parameters_and_terms_as_the_book_does():
    """`q` is the coordinates and `Q` the generalised forces in the book: the generated step
    calls the model's parameters `model_params`, the task's record `task_params`, and the
    reward terms `terms`."""
    env = gym.make("Lagrange/TwoLinkArm-v1")
    env.reset(seed=0)
    module = sys.modules[env.unwrapped._rt.stepper.fused.py_func.__module__]
    with open(module.__file__, encoding="utf-8") as fh:
        text = fh.read()
    assert "def step(actions, F_, B_, steps, O, C_, K_, model_params, task_params," in text
    assert "terms = matrix(F_, " in text
    assert not re.search(r"\b[pqQ]\b", text)


def test_a_new_fused_step_compiles_in_the_background_and_steps_the_same(monkeypatch):
    """A single env whose fused step numba's cache does not have steps by separate calls
    while the step compiles in a thread, then by the step: the same numbers bit for bit as
    an env that had its step from the first (the trajectory crosses the hand-over)."""
    from envs import step

    def run(env, steps=40):
        rng = np.random.default_rng(4)
        out = [env.reset(seed=2)[0]]
        for _ in range(steps):
            obs, r, term, _, info = env.step(rng.uniform(-1, 1, 1).astype(np.float32))
            out += [obs, [r, term, info["energy"]], info["state"]]
            if term:
                out.append(env.reset()[0])
        return np.concatenate([np.ravel(np.asarray(o, np.float64)) for o in out])

    steps = step.SEPARATE_FIRST + 40
    expected = run(gym.make("Examples/CartPole-v0"), steps)
    monkeypatch.setattr(step, "kernel_compiled", lambda kernel: False)  # not cached
    env = gym.make("Examples/CartPole-v0")
    stepper = env.unwrapped._rt.stepper
    got = run(env, steps)  # separate calls; the thread starts after SEPARATE_FIRST steps
    # the thread started (only it binds the step here), and may have handed its step over
    assert stepper.compiling or stepper.bound is not None
    assert np.array_equal(got, expected)
    step.wait_for_background()
    assert np.array_equal(run(env, steps), expected)  # its first step takes the thread's
    assert stepper.bound is not None and not stepper.compiling


def test_an_env_stepped_a_few_times_never_compiles_its_fused_step(monkeypatch):
    from envs import step

    monkeypatch.setattr(step, "kernel_compiled", lambda kernel: False)  # not cached
    env = gym.make("Examples/CartPole-v0")
    env.reset(seed=0)
    for _ in range(step.SEPARATE_FIRST):
        if any(env.step(env.action_space.sample())[2:4]):
            env.reset()
    stepper = env.unwrapped._rt.stepper
    assert not stepper.compiling and stepper.bound is None
    env.step(env.action_space.sample())  # one more: the step starts compiling
    assert stepper.compiling


@njit(cache=False)
def _views(flat, table):
    m = buffers.matrix(flat, 3, 2, 4)
    m[1, 2] = -1.0  # a view: written through to flat[3 + 1 * 4 + 2]
    c = buffers.column(table, 2)
    c[0] = -2.0
    return m.copy(), c.copy()


def test_the_step_s_unchecked_views_are_numpy_s_views():
    flat, table = np.arange(20.0), np.arange(12.0).reshape(3, 4)
    expected = flat[3:11].reshape(2, 4).copy(), table[:, 2].copy()
    expected[0][1, 2], expected[1][0] = -1.0, -2.0
    m, c = _views(flat, table)
    assert np.array_equal(m, expected[0]) and np.array_equal(c, expected[1])
    assert flat[9] == -1.0 and table[0, 2] == -2.0


def test_a_step_given_buffers_of_other_sizes_refuses_to_run():
    """The views into the flat buffers are not bounds-checked: the step checks the buffers'
    sizes once, before it makes them."""
    vec = gym.make_vec("Lagrange/TwoLinkArm-v1", 3, vectorization_mode="vector_entry_point")
    rt = bound(vec).unwrapped._rt
    step, a, store = rt.stepper, rt.arrays, rt.parameters
    args = [a.F, a.B, a.steps, a.O, step.C, step.K, store.model_params, store.task_params, -1]
    for k in (0, 1, 4):  # F_, B_, C_
        short = list(args)
        short[k] = args[k][:-1].copy()
        with pytest.raises(ValueError, match="sizes the step was made for"):
            step.bound(np.zeros((3, 2)), *short)
