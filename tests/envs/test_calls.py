"""A kernel called through its address (envs.calls): the same results as a direct call,
types checked when the caller compiles, and the fused step links no integrator."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from numba import njit, typeof
from numba.core.errors import TypingError

import envs  # noqa: F401  (registers the Lagrange ids)
from envs import calls
from tests.binding import bound


@njit(cache=False)
def scaled_sum(x, k, out):
    for i in range(x.shape[0]):
        out[i] = k * x[i] + out[i]


@njit(cache=False)
def caller(where, x, k, out):
    calls.call(where, "array(float64, 1d, C), int64, array(float64, 1d, C)", (x, k, out))


@njit(cache=False)
def caller_with_other_types(where, x, k, out):
    calls.call(where, "array(float64, 1d, C), float64, array(float64, 1d, C)", (x, k, out))


def test_a_call_through_the_address_is_the_direct_call():
    x, out = np.arange(5.0), np.ones(5)
    where = calls.address(scaled_sum, (typeof(x), typeof(3), typeof(out)))
    caller(where, x, 3, out)
    assert out.tolist() == (3 * x + 1).tolist()


def test_arguments_of_other_types_do_not_compile():
    x, out = np.arange(5.0), np.ones(5)
    where = calls.address(scaled_sum, (typeof(x), typeof(3), typeof(out)))
    with pytest.raises(TypingError, match=r"arguments \(.*int64.*\) are not the kernel's"):
        caller_with_other_types(where, x, 3, out)


@pytest.mark.parametrize("rows", [1, 9])  # erk_row one row at a time; erk_rows in lanes
def test_the_fused_step_calls_the_integrator_by_address(rows):
    vec = gym.make_vec("Lagrange/TwoLinkArm-v1", rows, vectorization_mode="vector_entry_point")
    rt = bound(vec).unwrapped._rt
    module = rt.system.kernel_module
    reached = rt._fused.py_func.__globals__.values()  # what numba would link into the step
    assert not any(v is module.erk_row or v is module.erk_rows for v in reached)
    assert rt._fused_K[rt._integrator_at] > 0  # the address, written when the step was bound
    obs = vec.reset(seed=0)[0]
    assert np.isfinite(vec.step(np.zeros(vec.action_space.shape, np.float32))[0]).all()
    assert not np.array_equal(obs, vec.unwrapped._rt.O)  # it moved


def test_a_step_without_the_integrator_s_address_refuses_to_run():
    vec = gym.make_vec("Lagrange/TwoLinkArm-v1", 1, vectorization_mode="vector_entry_point")
    rt = bound(vec).unwrapped._rt
    K = rt._fused_K.copy()
    K[rt._integrator_at] = 0  # as after unpickling, before bind_fused writes it
    actions = np.zeros((1, 2))
    with pytest.raises(RuntimeError, match="called before it was bound"):
        rt._fused_bound(actions, rt._F, rt._B, rt.steps, rt.O, rt._fused_C, K,
                        rt._model_params, rt._task_params, -1)  # fmt: skip


def test_a_copied_env_binds_its_own_address():
    """A pickled (or spawned) env rebuilds its step and writes the integrator's address
    when it is bound again; a deep copy too: neither steps through a stale one."""
    import copy
    import pickle

    vec = gym.make_vec("Lagrange/TwoLinkArm-v1", 9, vectorization_mode="vector_entry_point")
    bound(vec).reset(seed=2)
    a = np.full(vec.action_space.shape, 0.3, np.float32)
    vec.step(a)
    for twin in (pickle.loads(pickle.dumps(vec)), copy.deepcopy(vec)):
        rt = twin.unwrapped._rt
        assert rt._fused_bound is None and rt._fused_K[rt._integrator_at] == 0
        bound(twin)
        assert rt._fused_K[rt._integrator_at] == vec.unwrapped._rt._fused_K[rt._integrator_at]
    ref = copy.deepcopy(vec)
    for _ in range(5):
        assert np.array_equal(vec.step(a)[0], bound(ref).step(a)[0])
