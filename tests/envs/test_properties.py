"""Property-based checks of the env entry points (gym.make, reset, step, the vector env):
every input is accepted as documented or rejected by a ValueError or TypeError that names
the argument, and no output is NaN or inf."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

import envs  # noqa: F401  (registers the ids)

SETTINGS = settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
REALS = st.floats(allow_nan=True, allow_infinity=True) | st.sampled_from(
    [0.0, 1.0, -1.0, 0.5, 1e-300, 1e200, -1e300]
)
ODD = st.sampled_from([1 + 2j, 0j, "1.0", None, True])
NUMBER = REALS | ODD


def _finite_outputs(obs, reward, info) -> bool:
    values = [np.asarray(obs, dtype=float), np.asarray(reward, dtype=float), info["energy"]]
    return all(np.isfinite(v).all() for v in values) and np.isfinite(info["state"]).all()


@pytest.fixture(scope="module", params=["Lagrange/BeadOnRod-v1", "Lagrange/RollingDisk-v1"])
def env(request):
    return gym.make(request.param).unwrapped


@SETTINGS
@given(action=st.lists(NUMBER, min_size=0, max_size=3))
def test_step_accepts_real_finite_actions_of_the_right_shape_only(env, action):
    env.reset(seed=0)
    arr = np.asarray(action, dtype=object)
    ok_shape = len(action) == env.action_space.shape[0]
    real = all(isinstance(a, float) and not isinstance(a, bool) for a in action)
    try:
        obs, reward, term, trunc, info = env.step(np.array(action) if action else np.array([]))
    except (TypeError, ValueError) as exc:
        assert "action" in str(exc).lower(), exc
        assert not (ok_shape and real and np.isfinite(arr.astype(float)).all())
        return
    assert ok_shape
    assert _finite_outputs(obs, reward, info)
    assert env.observation_space.contains(obs)


@SETTINGS
@given(state=st.lists(REALS | st.sampled_from([1j]), min_size=1, max_size=11))
def test_reset_accepts_states_within_the_task_limits_only(env, state):
    n = env.system.state_size
    try:
        obs, info = env.reset(seed=0, options={"state": state})
    except (TypeError, ValueError) as exc:
        assert "options['state']" in str(exc) or "state" in str(exc), exc
        return
    x = np.asarray(state, dtype=complex)
    assert len(state) == n and np.isreal(x).all()
    assert np.isfinite(x.real).all() and (np.abs(x.real) <= env.plant.limits).all()
    assert np.isfinite(obs).all() and env.observation_space.contains(obs)
    obs, reward, *_, info = env.step(np.zeros(env.action_space.shape))
    assert _finite_outputs(obs, reward, info)


@SETTINGS
@given(
    key=st.sampled_from(["control_period", "substeps", "max_input"]),
    value=NUMBER | st.integers(-3, 3),
)
@example(key="control_period", value=2.225073858507203e-309)  # once: 1 / period overflowed
def test_make_accepts_documented_options_only(key, value):
    try:
        env = gym.make("Lagrange/BeadOnRod-v1", **{key: value}).unwrapped
    except (TypeError, ValueError) as exc:
        assert key in str(exc), exc
        return
    if value is None:  # the task's default
        pass
    elif key == "substeps":
        assert isinstance(value, int) and not isinstance(value, bool) and value >= 1
    else:
        assert isinstance(value, (int, float)) and not isinstance(value, bool)
        assert value > 0 and np.isfinite(value)
    obs, _ = env.reset(seed=0)
    assert np.isfinite(obs).all()


@SETTINGS
@given(rows=st.integers(0, 4), width=st.integers(0, 2))
def test_vector_reset_takes_one_goal_or_exactly_one_per_copy(rows, width):
    vec = gym.make_vec("Lagrange/BeadOnRod-v1", 3, vectorization_mode="vector_entry_point")
    goal = np.zeros((rows, width)) if rows else np.zeros(width)
    try:
        vec.reset(seed=0, options={"goal": goal})
    except ValueError as exc:
        assert "options['goal']" in str(exc)
        assert not ((rows in (0, 3)) and width == 1)
        return
    assert rows in (0, 3) and width == 1
