"""Per-copy model parameters and their simplest randomisation (`randomize=`): a copy with
given values steps bit for bit like an env made with them, resets draw afresh only for
the copies they reset, reproducibly, and an env without `randomize=` is unchanged."""

from __future__ import annotations

import re
import warnings

import gymnasium as gym
import numpy as np
import pytest

import envs
from agents.control.lqr_policy import LQRPolicy
from tests.binding import bound
from tests.matrix import over

ARM, ACROBOT = "Lagrange/TwoLinkArm-v1", "Lagrange/Acrobot-v2"
# the arm's per-copy steps by default (each model's per-copy lanes are compiled for these
# tests alone: the disk's 4 s of CPU cold), every model's with -m slow; the disk's per-copy
# fused step is checked by default against its recording (tests/envs/test_recorded.py)
PER_COPY_IDS = over(envs.ENV_IDS, fast=("Lagrange/TwoLinkArm-v1",))


def _vec(env_id, n, **kwargs):
    return gym.make_vec(env_id, n, vectorization_mode="vector_entry_point", **kwargs)


def _free_parameter(env_id):
    """A parameter no declared number of the task depends on (no warning when randomised),
    and a value of it 10 % above the nominal one."""
    nominal = gym.make(env_id).unwrapped.system.parameters
    for name, value in nominal.items():
        if value <= 0:
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            try:
                gym.make(env_id, randomize={name: (1.1 * value, 1.1 * value)})
            except RuntimeWarning:
                continue
        return name, 1.1 * value
    pytest.skip(f"every parameter of {env_id} sets a declared number")


@pytest.mark.parametrize("env_id", PER_COPY_IDS)
@pytest.mark.parametrize("fused", [True, False])
def test_one_copy_steps_bit_for_bit_like_a_single_env_made_with_its_values(env_id, fused):
    name, value = _free_parameter(env_id)
    n, row = 9, 4  # 9 rows: the integrator's vector lanes (8 rows and more)
    vec = _vec(env_id, n, randomize={})
    if fused:
        bound(vec)
    else:
        vec.unwrapped._rt.stepper.separate()  # the step of separate calls
    single = gym.make(env_id, **{name: value}).unwrapped
    values = np.full(n, vec.unwrapped.system.parameters[name])
    values[row] = value
    obs, info = vec.reset(seed=10, options={"params": {name: values}})
    o1, i1 = single.reset(seed=10 + row)
    assert info["params"][name].tolist() == values.tolist()
    assert np.array_equal(obs[row], o1)
    assert info["energy"][row] == i1["energy"]
    rng = np.random.default_rng(0)
    for _ in range(40):
        a = rng.uniform(-1, 1, vec.action_space.shape).astype(np.float32)
        obs, r, term, trunc, info = vec.step(a)
        o1, r1, t1, _, i1 = single.step(a[row])
        assert np.array_equal(obs[row], o1) and r[row] == r1 and term[row] == t1
        assert np.array_equal(info["state"][row], i1["state"])
        assert info["energy"][row] == i1["energy"]
        if "constraint_residual" in i1:
            assert np.array_equal(info["constraint_residual"][row], i1["constraint_residual"])
        if t1:
            break


def test_without_randomize_nothing_changes():
    """No `randomize=`: the env's numbers and info are those of an env without the
    feature, and `randomize={}` with no values given steps the same numbers."""
    plain, per_copy = _vec(ARM, 9), _vec(ARM, 9, randomize={})
    assert plain.unwrapped._rt.parameters.P is None
    o1, i1 = plain.reset(seed=3)
    o2, i2 = per_copy.reset(seed=3)
    assert "params" not in i1 and "params" in i2
    assert np.array_equal(o1, o2)
    rng = np.random.default_rng(1)
    for _ in range(20):
        a = rng.uniform(-1, 1, plain.action_space.shape).astype(np.float32)
        s1, s2 = plain.step(a), per_copy.step(a)
        for x, y in zip(s1[:4], s2[:4]):
            assert np.array_equal(x, y)
        assert np.array_equal(s1[4]["energy"], s2[4]["energy"])
    single = gym.make(ARM)
    assert "params" not in single.reset(seed=0)[1]


def test_resets_draw_each_copy_afresh_reproducibly_and_never_compound():
    ranges = {"Ibar1": (0.05, 0.1), "Ibar2": (0.06, 0.07)}
    vec = _vec(ARM, 6, randomize=ranges, max_episode_steps=3)
    _, info = vec.reset(seed=7)
    first = {k: info["params"][k].copy() for k in ranges}
    for k, (lo, hi) in ranges.items():
        assert ((lo <= first[k]) & (first[k] <= hi)).all()
        assert len(set(first[k].tolist())) == 6  # each copy its own draw
    nominal = vec.unwrapped.system.parameters
    assert info["params"]["m1"].tolist() == [nominal["m1"]] * 6  # the rest stay
    again = _vec(ARM, 6, randomize=ranges, max_episode_steps=3)
    _, info2 = again.reset(seed=7)
    for k in ranges:  # seeded: the same draws
        assert info2["params"][k].tolist() == first[k].tolist()
    # a single env seeded like copy 2 draws copy 2's values
    single = gym.make(ARM, randomize=ranges)
    _, i1 = single.reset(seed=9)
    assert [i1["params"][k] for k in ranges] == [first[k][2] for k in ranges]
    # autoreset (NEXT_STEP): after 3 steps every copy is truncated, the 4th step resets them
    a = np.zeros(vec.action_space.shape, dtype=np.float32)
    for _ in range(3):
        _, _, _, trunc, info = vec.step(a)
        assert info["params"]["Ibar1"].tolist() == first["Ibar1"].tolist()
    assert trunc.all()
    _, _, _, _, info = vec.step(a)
    for k, (lo, hi) in ranges.items():
        drawn = info["params"][k]
        assert ((lo <= drawn) & (drawn <= hi)).all()  # absolute: never compounds
        assert not np.array_equal(drawn, first[k])


def test_a_reset_of_some_copies_changes_only_theirs():
    vec = _vec(ARM, 4, randomize={"Ibar1": (0.05, 0.1)}, max_episode_steps=1000,
               autoreset_mode="SameStep")  # fmt: skip
    _, info = vec.reset(seed=1)
    before = info["params"]["Ibar1"].copy()
    rt = vec.unwrapped._rt
    x = rt.X.copy()
    x[2, 3] = 1e3  # beyond the elbow rate's limit: copy 2 diverges, resets in this step
    rt.X[:] = x
    _, _, term, _, info = vec.step(np.zeros(vec.action_space.shape, dtype=np.float32))
    assert term.tolist() == [False, False, True, False]
    after = info["params"]["Ibar1"]
    changed = after != before
    assert changed.tolist() == [False, False, True, False]


def test_exact_values_by_reset_options_hold_until_replaced():
    vec = _vec(ARM, 3, randomize={"Ibar1": (0.05, 0.1)}, max_episode_steps=2)
    _, info = vec.reset(seed=0, options={"params": {"Ibar1": 0.07, "m1": [1.0, 1.2, 1.4]}})
    assert info["params"]["Ibar1"].tolist() == [0.07] * 3
    assert info["params"]["m1"].tolist() == [1.0, 1.2, 1.4]
    a = np.zeros(vec.action_space.shape, dtype=np.float32)
    for _ in range(3):  # through an autoreset
        _, _, _, _, info = vec.step(a)
    assert info["params"]["Ibar1"].tolist() == [0.07] * 3
    assert info["params"]["m1"].tolist() == [1.0, 1.2, 1.4]
    _, info = vec.reset(seed=0, options={"params": {}})  # freed: drawn again, m1 nominal
    assert info["params"]["m1"].tolist() == [vec.unwrapped.system.parameters["m1"]] * 3
    assert len(set(info["params"]["Ibar1"].tolist())) == 3
    single = gym.make(ARM, randomize={})
    _, i1 = single.reset(options={"params": {"m2": 1.3}})
    assert i1["params"]["m2"] == 1.3 and isinstance(i1["params"]["m2"], float)


@pytest.mark.parametrize(
    "randomize, message",
    [
        ({"m22": (0.5, 1.5)}, "Did you mean 'm2'"),
        ({"m2": (0.0, 1.5)}, "must be positive, so low must be > 0"),
        ({"m2": (-1.0, 1.5)}, "must be positive"),
        ({"m2": (1.5, 0.5)}, "low <= high"),
        ({"m2": (0.5, np.inf)}, "finite"),
        ({"m2": 1.0}, "(low, high) pair"),
        ([("m2", (0.5, 1.5))], "must be a dict"),
    ],
)
def test_bad_declarations_are_refused_naming_the_problem(randomize, message):
    with pytest.raises((ValueError, TypeError), match=re.escape(message)):
        gym.make(ARM, randomize=randomize)


def test_bad_reset_values_are_refused_and_change_nothing():
    vec = _vec(ARM, 2, randomize={})
    vec.reset(seed=0)
    before = vec.unwrapped._rt.parameters.P.copy()
    for params, message in (
        ({"m2": -1.0}, "must be positive"),
        ({"mm2": 1.0}, "Did you mean 'm2'"),
        ({"m2": [1.0, 2.0, 3.0]}, r"shape \(2,\)"),
        ({"m2": np.nan}, "finite"),
    ):
        with pytest.raises(ValueError, match=message):
            vec.reset(options={"params": params})
        assert np.array_equal(vec.unwrapped._rt.parameters.P, before)
    with pytest.raises(ValueError, match="needs an env made with randomize="):
        gym.make(ARM).reset(options={"params": {"m2": 1.0}})


def test_a_declared_number_that_stays_nominal_is_named():
    with pytest.warns(RuntimeWarning, match="input_high, input_low depend.* randomised 'm2'"):
        gym.make(ACROBOT, randomize={"m2": (0.8, 1.2)})


def test_lqr_keeps_the_nominal_model():
    """The controller designs on the env's nominal system, whatever the copies draw."""
    env = gym.make(ARM, randomize={"Ibar2": (0.1, 0.2)})
    _, info = env.reset(seed=0)
    nominal = gym.make(ARM).unwrapped.system.parameters
    assert env.unwrapped.system.parameters == nominal
    assert info["params"]["Ibar2"] >= 0.1 > nominal["Ibar2"]
    plain = gym.make(ARM)
    plain.reset(seed=0)
    x0, u0 = plain.unwrapped.operating_point()
    policy, reference = LQRPolicy(env), LQRPolicy(plain)
    assert policy.system.parameters == nominal
    assert np.array_equal(policy.design(x0, u0).K, reference.design(x0, u0).K)


@pytest.mark.slow  # the per-copy threaded kernels, compiled for this test alone (3.4 s of CPU)
def test_threads_step_per_copy_parameters_as_one_thread_does():
    """Blocks of rows spread over threads (no fused step) read each row's own values."""
    n = 130  # more than one block of 64 rows
    values = np.linspace(0.05, 0.12, n)
    pair = [_vec(ARM, n, randomize={}, num_threads=t) for t in (1, 2)]
    assert pair[1].unwrapped._rt.stepper.fused is None
    out = []
    for vec in pair:
        vec.reset(seed=2, options={"params": {"Ibar2": values}})
        a = np.full(vec.action_space.shape, 0.3, dtype=np.float32)
        for _ in range(5):
            obs = vec.step(a)[0]
        out.append(obs)
    assert np.array_equal(out[0], out[1])
