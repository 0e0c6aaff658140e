"""A task's default randomisation (`Task(randomize=...)`) and the drawn parameters as
observation features (`observe_params=`)."""

from __future__ import annotations

import dataclasses
import re
import warnings

import gymnasium as gym
import numpy as np
import pytest

import envs
from agents.control.lqr_policy import LQRPolicy
from envs import LagrangianEnv, LagrangianVectorEnv
from envs.checks import DeclarationError
from envs.randomize import Uniform
from tests.binding import bound

ARM = "Lagrange/TwoLinkArm-v1"
DEFAULT = {"Ibar1": (0.05, 0.1)}
TASK = dataclasses.replace(envs.tasks.arm.TASK, randomize=DEFAULT)


def test_a_task_s_randomize_is_the_default_the_option_replaces_or_turns_off():
    _, info = LagrangianEnv(TASK).reset(seed=3)
    assert (
        info["params"]["Ibar1"]
        == gym.make(ARM, randomize=DEFAULT).reset(seed=3)[1]["params"]["Ibar1"]
    )
    # randomize=None (as given by code that passes every option) keeps the task's default
    assert LagrangianEnv(TASK, randomize=None).reset(seed=3)[1]["params"] == info["params"]
    off = LagrangianEnv(TASK, randomize=False)
    assert off._rt.parameters.P is None and "params" not in off.reset(seed=3)[1]
    other = LagrangianEnv(TASK, randomize={"Ibar2": (0.06, 0.07)}).reset(seed=3)[1]["params"]
    assert other["Ibar1"] == 1 / 12  # replaced, not merged: Ibar1 nominal
    assert 0.06 <= other["Ibar2"] <= 0.07
    vec = LagrangianVectorEnv(TASK, num_envs=3)
    assert vec.reset(seed=3)[1]["params"]["Ibar1"][0] == info["params"]["Ibar1"]
    # the built-in envs declare none: unchanged, and False is accepted there too
    assert gym.make(ARM).unwrapped._rt.parameters.P is None
    assert gym.make(ARM, randomize=False).unwrapped._rt.parameters.P is None


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
        dataclasses.replace(envs.tasks.arm.TASK, randomize=randomize)


def test_a_task_s_randomize_naming_no_parameter_is_refused_when_the_env_is_made():
    task = dataclasses.replace(envs.tasks.arm.TASK, randomize={"m22": (0.5, 1.0)})
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
    table = envs.docs.describe(envs.tasks.arm.TASK, randomize=DEFAULT, observe_params=True)
    assert "| 14 | param Ibar1 | 0.05 | 0.1 |  |" in table
    assert "param" not in envs.docs.describe(envs.tasks.arm.TASK)


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


ACROBOT, CRANK = "Lagrange/Acrobot-v2", "Lagrange/CrankSlider-v1"


@pytest.mark.parametrize("fused", [True, False])
def test_task_functions_read_each_copy_s_own_parameters(fused):
    """Acrobot-v2's height term reads p.l and p.l2: a copy with its own l pays, bit for
    bit, what a single env made with that l pays."""
    n, row = 9, 4
    vec = gym.make_vec(ACROBOT, n, vectorization_mode="vector_entry_point", randomize={})
    assert vec.unwrapped._rt.parameters.follows
    if fused:
        bound(vec)
    else:
        vec.unwrapped._rt.stepper.separate()
    values = np.full(n, 1.0)
    values[row] = 1.1
    vec.reset(seed=10, options={"params": {"l": values}})
    single = gym.make(ACROBOT, l=1.1)
    single.reset(seed=10 + row)
    rng = np.random.default_rng(0)
    for _ in range(50):
        a = rng.uniform(-1, 1, vec.action_space.shape).astype(np.float32)
        obs, r, _, _, info = vec.step(a)
        o1, r1, _, _, i1 = single.step(a[row])
        assert np.array_equal(obs[row], o1) and r[row] == r1
        assert info["reward_terms"]["height"][row] == i1["reward_terms"]["height"]
    # nothing left to warn about for l: the dynamics and the height term both follow
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        gym.make(ACROBOT, randomize={"l": (0.9, 1.1)})


def test_constants_are_computed_at_each_copy_s_values():
    """CrankSlider's constants (half travel, reach, ...) follow R; its goal range and
    observation bounds stay nominal (the warning says so), so the start is given."""
    with pytest.warns(RuntimeWarning, match=r"goal_high.*randomised 'R'.*record p follow"):
        vec = gym.make_vec(CRANK, 3, vectorization_mode="vector_entry_point",
                           randomize={"R": (0.09, 0.11)})  # fmt: skip
    single = gym.make(CRANK, R=0.105)
    _, i1 = single.reset(seed=0)
    start = {"state": np.tile(i1["state"], (3, 1)), "goal": np.tile(i1["goal"], (3, 1))}
    vec.reset(seed=0, options={"params": {"R": [0.1, 0.105, 0.095]}, **start})
    p_rows = vec.unwrapped._rt.parameters.records
    assert p_rows[1] == single.unwrapped.plant.p  # every constant, recomputed
    assert p_rows.half_travel[0] == gym.make(CRANK).unwrapped.plant.p.half_travel
    # recomputed only where a parameter they read (R, l, h: the linkage) moved
    read = vec.unwrapped.plant.constant_inputs
    assert [k for k, r in zip(vec.unwrapped.system.parameters, read) if r] == ["R", "l", "h"]
    for _ in range(30):
        a = np.full(vec.action_space.shape, 0.3, dtype=np.float32)
        r = vec.step(a)[1]
        assert r[1] == single.step(a[1])[1]


def test_a_task_function_that_cannot_read_p_by_row_keeps_it_nominal_and_is_named():
    def height(x, a, goal, p):  # a scalar use of p: one record for all rows only
        return np.full(len(x.theta1), float(p.l) - 1.0)

    base = envs.tasks.acrobot.TASK_V2
    terms = tuple(dataclasses.replace(t, fn=height) if t.name == "height" else t
                  for t in base.terms)  # fmt: skip
    task = dataclasses.replace(base, name="AcrobotScalarP", terms=terms)
    with pytest.warns(RuntimeWarning, match="task function 'height' depend.* randomised 'l'"):
        env = LagrangianEnv(task, randomize={"l": (0.9, 1.1)})
    assert not env._rt.parameters.follows and env._rt.parameters.records is None


def test_the_nominal_warning_compares_supports_where_the_plant_is_built():
    """The store builds no plant: whether the record follows each copy is the plant's fact,
    found by `Plant.build`; a plant keeps no second copy of its parameters by name."""
    import dataclasses
    from pathlib import Path

    from envs import parameters
    from envs.plant import Plant

    source = Path(parameters.__file__).read_text(encoding="utf-8")
    assert "Plant.build" not in source and "from .plant" not in source
    fields = {f.name for f in dataclasses.fields(Plant)}
    assert "params" not in fields and {"follows", "constant_inputs"} <= fields
