"""A kernel called through its address (dynamics.calls): the same results as a direct call,
types checked when the caller compiles, and the fused step links no kernel."""

from __future__ import annotations

import inspect

import gymnasium as gym
import numpy as np
import pytest
from numba import njit, typeof
from numba.core.errors import TypingError

import envs  # noqa: F401  (registers the Lagrange ids)
from dynamics import calls, stepping
from tests.binding import bound


@njit(cache=False)
def scaled_sum(x, k, out):
    for i in range(x.shape[0]):
        out[i] = k * x[i] + out[i]


@njit(cache=False)
def norm(x):
    return np.sqrt((x * x).sum()), x * 2.0


SUM = "tests.envs.test_calls.scaled_sum(array(float64, 1d, C), int64, array(float64, 1d, C))"
NORM = "tests.envs.test_calls.norm(array(float64, 1d, C))"


@njit(cache=False)
def caller(where, x, k, out):
    calls.call(where, SUM, (x, k, out))


@njit(cache=False)
def caller_with_other_types(where, x, k, out):
    calls.call(where, SUM, (x, 1.0 * k, out))


@njit(cache=False)
def caller_of_norm(where, x):
    length, doubled = calls.call(where, NORM, (x,))
    return length + doubled[0]


def test_a_call_through_the_address_is_the_direct_call():
    x, out = np.arange(5.0), np.ones(5)
    signature = (typeof(x), typeof(3), typeof(out))
    assert calls.label(scaled_sum, signature) == SUM
    caller(calls.address(scaled_sum, signature), x, 3, out)
    assert out.tolist() == (3 * x + 1).tolist()


def test_a_call_gives_the_kernel_s_result():
    x = np.array([3.0, 4.0])
    where = calls.address(norm, (typeof(x),))
    assert caller_of_norm(where, x) == 5.0 + 6.0  # a tuple holding a new array comes back


def test_arguments_of_other_types_do_not_compile():
    x, out = np.arange(5.0), np.ones(5)
    where = calls.address(scaled_sum, (typeof(x), typeof(3), typeof(out)))
    with pytest.raises(TypingError, match=r"arguments \(.*float64.*\) are not those of"):
        caller_with_other_types(where, x, 3, out)


def slots(rt):
    return [slot for slot, *_ in rt.stepper.calls]


@pytest.mark.parametrize("rows", [1, 9])  # erk_row one row at a time; erk_rows in lanes
def test_the_fused_step_calls_every_kernel_by_address(rows):
    vec = gym.make_vec("Lagrange/TwoLinkArm-v1", rows, vectorization_mode="vector_entry_point")
    rt = bound(vec).unwrapped._rt
    step = rt.stepper
    assert step.calls[0][1] is (stepping.erk_row if rows == 1 else stepping.erk_rows)
    table = step.K[step.table_slot :][: stepping.TABLE_SIZE]  # the model's kernels
    assert table[stepping.AT_DERIVATIVE] != 0
    reached = step.fused.py_func.__globals__.values()  # what numba would link into the step
    assert [v for v in reached if hasattr(v, "py_func") and v is not step.fused] == []
    assert "_call(addresses[" in inspect.getsource(step.fused.py_func)
    assert (step.K[slots(rt)] > 0).all()  # the addresses, written when it was bound
    obs = vec.reset(seed=0)[0]
    assert np.isfinite(vec.step(np.zeros(vec.action_space.shape, np.float32))[0]).all()
    assert not np.array_equal(obs, vec.unwrapped._rt.O)  # it moved


def test_a_step_without_an_address_refuses_to_run():
    vec = gym.make_vec("Lagrange/TwoLinkArm-v1", 1, vectorization_mode="vector_entry_point")
    rt = bound(vec).unwrapped._rt
    step, a, store = rt.stepper, rt.arrays, rt.parameters
    K = step.K.copy()
    K[slots(rt)[-1]] = 0  # as after unpickling, before the step is bound
    actions = np.zeros((1, 2))
    with pytest.raises(RuntimeError, match="called before it was bound"):
        step.bound(actions, a.F, a.B, a.steps, a.O, step.C, K, store.model_params,
                   store.task_params, -1)  # fmt: skip


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
        step = rt.stepper
        assert step.bound is None and (step.K[slots(rt)] == 0).all()
        assert step.K[step.table_slot] == 0  # the model's table too
        bound(twin)
        assert (step.K == vec.unwrapped._rt.stepper.K).all()
    ref = copy.deepcopy(vec)
    for _ in range(5):
        assert np.array_equal(vec.step(a)[0], bound(ref).step(a)[0])
