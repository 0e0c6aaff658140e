"""The declared forms of `randomize=` (envs.randomize): distributions, how a draw applies
and when, each seeded, never compounding, refused when it could reach impossible values,
and a vector env's copy stepping like a single env seeded like it."""

from __future__ import annotations

import math
import re

import gymnasium as gym
import numpy as np
import pytest
from scipy import stats

from envs.randomize import Choice, LogUniform, TruncNormal, Uniform, distribution

ARM = "Lagrange/TwoLinkArm-v1"
NOMINAL_I = 1 / 12  # the arm's Ibar1 and Ibar2 (kg m^2): no declared number depends on them


def _vec(n, **kwargs):
    return gym.make_vec(ARM, n, vectorization_mode="vector_entry_point", **kwargs)


def _zeros(vec):
    return np.zeros(vec.action_space.shape, dtype=np.float32)


def test_the_simple_form_the_dataclass_and_the_dict_draw_the_same_values():
    forms = (
        {"Ibar1": (0.05, 0.1)},
        {"Ibar1": Uniform(0.05, 0.1)},
        {"Ibar1": {"dist": "uniform", "low": 0.05, "high": 0.1, "when": "reset"}},
    )
    drawn = [_vec(5, randomize=f).reset(seed=4)[1]["params"]["Ibar1"].tolist() for f in forms]
    assert drawn[0] == drawn[1] == drawn[2]
    assert len(set(drawn[0])) == 5


@pytest.mark.parametrize(
    "dist, low, high",
    [
        (Uniform(0.8, 1.2, apply="scale"), 0.8 * NOMINAL_I, 1.2 * NOMINAL_I),
        (Uniform(-0.02, 0.02, apply="offset"), NOMINAL_I - 0.02, NOMINAL_I + 0.02),
        ({"dist": "loguniform", "low": 0.5, "high": 2.0, "apply": "scale"}, 0.5 * NOMINAL_I,
         2.0 * NOMINAL_I),
    ],
)  # fmt: skip
def test_scale_and_offset_apply_to_the_nominal_value_so_resets_never_compound(dist, low, high):
    vec = _vec(4, randomize={"Ibar1": dist}, max_episode_steps=1)
    _, info = vec.reset(seed=0)
    seen = [info["params"]["Ibar1"].copy()]
    for _ in range(40):  # every other step autoresets every copy (NEXT_STEP)
        seen.append(vec.step(_zeros(vec))[4]["params"]["Ibar1"].copy())
    seen = np.array(seen)
    # 21 draws of each copy: were they compounding, a product or sum of 21 factors or
    # offsets would leave the range; 1e-15 relative: one rounding of the product or sum
    assert (seen >= low * (1 - 1e-15)).all() and (seen <= high * (1 + 1e-15)).all()
    assert len(np.unique(seen)) == 21 * 4
    # the single env reaches the same values from the same seed (copy 0: seed 0)
    single = gym.make(ARM, randomize={"Ibar1": dist})
    assert single.reset(seed=0)[1]["params"]["Ibar1"] == seen[0, 0]


def test_scale_reads_the_env_s_own_nominal_value():
    env = gym.make(ARM, Ibar1=0.07, randomize={"Ibar1": Uniform(2.0, 2.0, apply="scale")})
    for seed in (0, 1, None):
        assert env.reset(seed=seed)[1]["params"]["Ibar1"] == 0.14


def test_every_k_steps_changes_only_the_due_copies_at_multiples_of_their_steps():
    k = 3
    declared = {
        "Ibar1": {"dist": "uniform", "low": 0.05, "high": 0.1, "when": k},
        "Ibar2": (0.06, 0.07),  # at resets only
    }
    vec = _vec(4, randomize=declared, max_episode_steps=1000, autoreset_mode="SameStep")
    _, info = vec.reset(seed=3)
    rt = vec.unwrapped._rt
    history = [info["params"]["Ibar1"].copy()]
    ibar2 = info["params"]["Ibar2"].copy()
    steps = [rt.steps.copy()]
    for t in range(1, 13):
        if t == 2:  # copy 1 diverges in step 2 and starts afresh within it (SameStep)
            rt.X[1, 3] = 1e3
        _, _, term, _, info = vec.step(_zeros(vec))
        assert term[1] == (t == 2) and not term[[0, 2, 3]].any()
        history.append(info["params"]["Ibar1"].copy())
        steps.append(rt.steps.copy())
        if t == 2:  # copy 1's reset drew its Ibar2 afresh
            assert (info["params"]["Ibar2"] != ibar2).tolist() == [False, True, False, False]
            ibar2 = info["params"]["Ibar2"].copy()
        assert np.array_equal(info["params"]["Ibar2"], ibar2)  # else unchanged mid-episode
    history, steps = np.array(history), np.array(steps)
    changed = history[1:] != history[:-1]
    for i in range(4):
        for t in range(1, 13):
            reset_now = i == 1 and t == 2
            due = steps[t, i] % k == 0 and steps[t, i] > 0
            assert changed[t - 1, i] == (due or reset_now), (i, t)
    assert changed[:, 0].sum() == 4 and changed[:, 1].sum() == 4  # 3, 6, 9, 12; 2, 5, 8, 11
    assert ((0.05 <= history) & (history <= 0.1)).all()


def test_every_k_steps_in_a_vector_copy_as_in_a_single_env_with_its_seed():
    declared = {"Ibar2": LogUniform(0.05, 0.12, when=2)}
    vec = _vec(3, randomize=declared, observe_params=True, max_episode_steps=7)
    single = gym.make(ARM, randomize=declared, observe_params=True, max_episode_steps=7)
    obs, info = vec.reset(seed=20)
    o1, i1 = single.reset(seed=22)
    assert np.array_equal(obs[2], o1) and info["params"]["Ibar2"][2] == i1["params"]["Ibar2"]
    rng = np.random.default_rng(5)
    for _ in range(7):  # the 7th step truncates
        a = rng.uniform(-1, 1, vec.action_space.shape).astype(np.float32)
        obs, r, _, trunc, info = vec.step(a)
        o1, r1, _, tr1, i1 = single.step(a[2])
        assert np.array_equal(obs[2], o1) and r[2] == r1 and trunc[2] == tr1
        assert info["params"]["Ibar2"][2] == i1["params"]["Ibar2"]
        assert o1[-1] == np.float32(i1["params"]["Ibar2"])  # the context feature follows
    o1, i1 = single.reset()  # the single env's next episode; the vector's autoresets
    obs, *_, info = vec.step(a)
    assert np.array_equal(obs[2], o1) and info["params"]["Ibar2"][2] == i1["params"]["Ibar2"]


def test_construction_draws_hold_across_resets_until_a_reset_given_a_seed():
    declared = {"Ibar1": Uniform(0.05, 0.1, when="construction"), "Ibar2": (0.06, 0.07)}
    vec = _vec(3, randomize=declared, max_episode_steps=1)
    _, info = vec.reset(seed=8)
    fixed, first_ibar2 = info["params"]["Ibar1"].copy(), info["params"]["Ibar2"].copy()
    assert len(set(fixed.tolist())) == 3  # each copy its own
    for _ in range(4):  # autoresets: Ibar2 drawn afresh, Ibar1 kept
        info = vec.step(_zeros(vec))[4]
        assert np.array_equal(info["params"]["Ibar1"], fixed)
    assert not np.array_equal(info["params"]["Ibar2"], first_ibar2)
    assert np.array_equal(vec.reset()[1]["params"]["Ibar1"], fixed)  # unseeded: kept
    again = vec.reset(seed=8)[1]["params"]  # seeded: as a fresh env
    assert np.array_equal(again["Ibar1"], fixed) and np.array_equal(again["Ibar2"], first_ibar2)
    assert not np.array_equal(vec.reset(seed=9)[1]["params"]["Ibar1"], fixed)
    single = gym.make(ARM, randomize=declared)
    assert single.reset(seed=9)[1]["params"]["Ibar1"] == fixed[1]
    assert single.reset()[1]["params"]["Ibar1"] == fixed[1]


def test_truncated_normal_stays_within_its_bounds_and_is_normal_inside():
    d = TruncNormal(1.0, 0.5, 0.2, 1.3)
    rng = np.random.default_rng(0)
    x = np.array([d.sample(rng) for _ in range(20000)])
    assert x.min() >= 0.2 and x.max() <= 1.3
    cdf = stats.truncnorm((0.2 - 1) / 0.5, (1.3 - 1) / 0.5, loc=1, scale=0.5).cdf
    # Kolmogorov-Smirnov against scipy's truncated normal: the 99.9 % critical value of the
    # statistic for n = 20000 is 1.95 / sqrt(n) = 0.0138 (seeded, so this is one fixed draw)
    assert stats.kstest(x, cdf).statistic < 1.95 / math.sqrt(len(x))
    # far in the upper tail (mirrored into the lower one): still inside, not all at a bound
    tail = TruncNormal(0.0, 1.0, 8.0, 9.0)
    y = np.array([tail.sample(rng) for _ in range(200)])
    assert y.min() >= 8.0 and y.max() <= 9.0 and len(np.unique(y)) == 200


def test_log_uniform_draws_have_a_uniform_logarithm():
    d = LogUniform(0.1, 10.0)
    rng = np.random.default_rng(1)
    x = np.array([d.sample(rng) for _ in range(20000)])
    critical = 1.95 / math.sqrt(len(x))  # KS, 99.9 % (see the truncated normal's test)
    log_uniform = stats.uniform(math.log(0.1), math.log(100.0)).cdf
    assert stats.kstest(np.log(x), log_uniform).statistic < critical
    # the test can fail: the draws themselves are far from uniform on [0.1, 10]
    assert stats.kstest(x, stats.uniform(0.1, 9.9).cdf).statistic > 10 * critical


def test_choice_draws_only_its_values_with_their_weights():
    d = distribution({"dist": "choice", "values": [0.5, 1.0, 2.0], "weights": [1, 2, 1]})
    rng = np.random.default_rng(2)
    x = np.array([d.sample(rng) for _ in range(8000)])
    assert set(x.tolist()) == {0.5, 1.0, 2.0}
    # binomial: the share of 1.0 has std sqrt(0.25 / 8000) = 0.0056; 4 std: 0.022
    assert abs((x == 1.0).mean() - 0.5) < 0.022
    vec = _vec(16, randomize={"Ibar1": Choice((0.07, 0.09))})
    assert set(vec.reset(seed=0)[1]["params"]["Ibar1"].tolist()) == {0.07, 0.09}


@pytest.mark.parametrize(
    "declared, message",
    [
        ({"m2": Uniform(-1.0, 1.0, apply="scale")}, "must be positive, so low must be > 0"),
        ({"m2": Uniform(-1.5, 0.0, apply="offset")}, "lowest value it reaches is -0.5"),
        ({"m2": {"dist": "logunifrom", "low": 1, "high": 2}}, "Did you mean 'loguniform'"),
        ({"m2": {"dist": "uniform", "low": 1, "hi": 2}}, "uniform takes low, high, apply, when"),
        ({"m2": {"dist": "truncnormal", "mean": 1, "std": 0.1}}, "missing 2 required"),
        ({"m2": {"dist": "loguniform", "low": 0.0, "high": 2}}, "LogUniform needs 0 < low"),
        ({"m2": {"dist": "truncnormal", "mean": 1, "std": 0, "low": 0.5, "high": 2}}, "std > 0"),
        ({"m2": {"dist": "truncnormal", "mean": 1, "std": 0.01, "low": 3, "high": 4}},
         "hold no probability"),  # 200 std above the mean
        ({"m2": {"dist": "choice", "values": []}}, "non-empty sequence"),
        ({"m2": {"dist": "choice", "values": [1, 2], "weights": [1, -1]}}, "finite numbers >= 0"),
        ({"m2": {"dist": "uniform", "low": 1, "high": 2, "apply": "multiply"}}, "apply must be"),
        ({"m2": {"dist": "uniform", "low": 1, "high": 2, "when": 0}}, "whole number of steps"),
        ({"m2": {"dist": "uniform", "low": 1, "high": 2, "when": True}}, "whole number"),
        ({"m2": {"dist": "uniform", "low": 2, "high": 1}}, "low <= high"),
    ],
)  # fmt: skip
def test_bad_distributions_are_refused_naming_the_problem(declared, message):
    with pytest.raises((ValueError, TypeError), match=re.escape(message)):
        gym.make(ARM, randomize=declared)


def test_values_given_by_reset_options_hold_through_every_k_step_redraws():
    vec = _vec(
        2, randomize={"Ibar1": Uniform(0.05, 0.1, when=2), "Ibar2": Uniform(0.06, 0.07, when=2)}
    )
    vec.reset(seed=0, options={"params": {"Ibar1": [0.055, 0.065]}})
    for _ in range(4):
        info = vec.step(_zeros(vec))[4]
    assert info["params"]["Ibar1"].tolist() == [0.055, 0.065]
    assert not np.array_equal(info["params"]["Ibar2"], vec.reset(seed=0)[1]["params"]["Ibar2"])


def test_a_pickled_env_draws_on_as_the_original():
    import pickle

    declared = {
        "Ibar1": Uniform(0.05, 0.1, when=3),
        "Ibar2": Uniform(0.06, 0.07, when="construction"),
    }
    vec = _vec(3, randomize=declared, observe_params=True, max_episode_steps=5)
    vec.reset(seed=1)
    vec.step(_zeros(vec))
    twin = pickle.loads(pickle.dumps(vec))
    for _ in range(8):
        a, b = vec.step(_zeros(vec)), twin.step(_zeros(twin))
        assert np.array_equal(a[0], b[0])
        assert all(np.array_equal(a[4]["params"][k], b[4]["params"][k]) for k in declared)


def test_gymnasium_s_sync_vector_env_of_single_envs_matches_the_native_one():
    declared = {
        "Ibar1": Uniform(0.05, 0.1),
        "Ibar2": {"dist": "truncnormal", "mean": 0.08, "std": 0.01, "low": 0.06, "high": 0.1,
                  "when": 5},
    }  # fmt: skip
    made = [
        gym.make_vec(ARM, 3, vectorization_mode=mode, randomize=declared, observe_params=True)
        for mode in ("sync", "vector_entry_point")
    ]
    assert np.array_equal(made[0].reset(seed=5)[0], made[1].reset(seed=5)[0])
    rng = np.random.default_rng(3)
    for _ in range(12):  # through two redraws of Ibar2
        a = rng.uniform(-1, 1, made[0].action_space.shape).astype(np.float32)
        assert np.array_equal(made[0].step(a)[0], made[1].step(a)[0])
