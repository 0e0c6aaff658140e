"""A task's default randomisation (`Task(randomize=...)`) and the drawn parameters as
observation features (`observe_params=`)."""

from __future__ import annotations

import dataclasses
import re

import gymnasium as gym
import numpy as np
import pytest

import envs
from agents.lqr_policy import LQRPolicy
from envs import LagrangianEnv, LagrangianVectorEnv
from envs.checks import DeclarationError
from envs.randomize import Uniform

ARM = "Lagrange/TwoLinkArm-v1"
DEFAULT = {"Ibar1": (0.05, 0.1)}
TASK = dataclasses.replace(envs.arm.TASK, randomize=DEFAULT)


def test_a_task_s_randomize_is_the_default_the_option_replaces_or_turns_off():
    _, info = LagrangianEnv(TASK).reset(seed=3)
    assert (
        info["params"]["Ibar1"]
        == gym.make(ARM, randomize=DEFAULT).reset(seed=3)[1]["params"]["Ibar1"]
    )
    # randomize=None (as given by code that passes every option) keeps the task's default
    assert LagrangianEnv(TASK, randomize=None).reset(seed=3)[1]["params"] == info["params"]
    off = LagrangianEnv(TASK, randomize=False)
    assert off._rt.P is None and "params" not in off.reset(seed=3)[1]
    other = LagrangianEnv(TASK, randomize={"Ibar2": (0.06, 0.07)}).reset(seed=3)[1]["params"]
    assert other["Ibar1"] == 1 / 12  # replaced, not merged: Ibar1 nominal
    assert 0.06 <= other["Ibar2"] <= 0.07
    vec = LagrangianVectorEnv(TASK, num_envs=3)
    assert vec.reset(seed=3)[1]["params"]["Ibar1"][0] == info["params"]["Ibar1"]
    # the built-in envs declare none: unchanged, and False is accepted there too
    assert gym.make(ARM).unwrapped._rt.P is None
    assert gym.make(ARM, randomize=False).unwrapped._rt.P is None


@pytest.mark.parametrize(
    "randomize, message",
    [
        ([("Ibar1", (0.05, 0.1))], "`randomize` must be a dict"),
        ({"Ibar1": {"dist": "gaussian"}}, "unknown dist 'gaussian'"),
        ({"Ibar1": (0.1, 0.05)}, "low <= high"),
    ],
)
def test_a_task_s_bad_randomize_is_refused_when_declared(randomize, message):
    with pytest.raises(DeclarationError, match=re.escape(message)):
        dataclasses.replace(envs.arm.TASK, randomize=randomize)


def test_a_task_s_randomize_naming_no_parameter_is_refused_when_the_env_is_made():
    task = dataclasses.replace(envs.arm.TASK, randomize={"m22": (0.5, 1.0)})
    with pytest.raises(ValueError, match="Did you mean 'm2'"):
        LagrangianEnv(task)


def test_observed_parameters_follow_the_declared_features_within_their_supports():
    declared = {"Ibar1": (0.05, 0.1), "Ibar2": Uniform(0.9, 1.1, apply="scale")}
    plain = gym.make_vec(ARM, 4, vectorization_mode="vector_entry_point", randomize=declared)
    vec = gym.make_vec(
        ARM, 4, vectorization_mode="vector_entry_point", randomize=declared, observe_params=True
    )
    space = vec.single_observation_space
    n = plain.single_observation_space.shape[0]
    assert space.shape == (n + 2,)
    assert space.low[n:].tolist() == [np.float32(0.05), np.float32(0.9 / 12)]
    assert space.high[n:].tolist() == [np.float32(0.1), np.float32(1.1 / 12)]
    o_plain, _ = plain.reset(seed=1)
    obs, info = vec.reset(seed=1)
    assert np.array_equal(obs[:, :n], o_plain)
    expected = np.stack([info["params"]["Ibar1"], info["params"]["Ibar2"]], axis=1)
    assert np.array_equal(obs[:, n:], expected.astype(np.float32))
    a = np.full(vec.action_space.shape, 0.2, dtype=np.float32)
    for _ in range(5):
        obs, *_ = vec.step(a)
        o_plain, *_ = plain.step(a)
    assert np.array_equal(obs[:, :n], o_plain)
    assert np.array_equal(obs[:, n:], expected.astype(np.float32))  # held through steps
    assert space.contains(obs[0])
    # agents that rebuild the state from the observation ignore the extra columns
    u = vec.unwrapped
    assert np.array_equal(
        u.state_from_observation(obs), plain.unwrapped.state_from_observation(o_plain)
    )
    single = gym.make(ARM, randomize=declared, observe_params=True)
    o1, _ = single.reset(seed=0)
    policy = LQRPolicy(single.unwrapped)
    assert policy.predict(o1)[0].shape == single.action_space.shape


def test_a_given_value_outside_the_support_is_clipped_in_the_observation_only():
    env = gym.make(ARM, randomize=DEFAULT, observe_params=("Ibar1",))
    obs, info = env.reset(seed=0, options={"params": {"Ibar1": 0.2}})
    assert info["params"]["Ibar1"] == 0.2 and obs[-1] == np.float32(0.1)
    obs, info = env.reset(seed=0, options={"params": {}})
    assert obs[-1] == np.float32(info["params"]["Ibar1"])


def test_observed_parameters_appear_in_the_observation_table():
    table = envs.docs.describe(envs.arm.TASK, randomize=DEFAULT, observe_params=True)
    assert "| 14 | param Ibar1 | 0.05 | 0.1 |  |" in table
    assert "param" not in envs.docs.describe(envs.arm.TASK)


@pytest.mark.parametrize(
    "options, message",
    [
        ({"observe_params": True}, "observe_params needs randomised parameters"),
        ({"observe_params": True, "randomize": {}}, "observe_params needs randomised"),
        ({"observe_params": ("m2",), "randomize": DEFAULT}, "'m2', which is not randomised"),
        ({"observe_params": "Ibar1", "randomize": DEFAULT}, "True, False or a tuple"),
    ],
)
def test_bad_observe_params_are_refused(options, message):
    with pytest.raises((ValueError, TypeError), match=re.escape(message)):
        gym.make(ARM, **options)
