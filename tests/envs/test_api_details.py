"""Details of the single and vector env's API: byte order, seeds, refused resets and the
autoreset mode (what a user can hand them that the checkers do not try)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import envs  # noqa: F401  (registers the envs)

BEAD = "Lagrange/BeadOnRod-v1"


def _vec(n=2, **kwargs):
    return gym.make_vec(BEAD, n, vectorization_mode="vector_entry_point", **kwargs)


def test_a_big_endian_action_steps_like_a_native_one():
    """The single env's fast path hands native float arrays to the compiled step as they
    are; another byte order is converted (it failed inside numba)."""
    native, swapped = gym.make(BEAD), gym.make(BEAD)
    native.reset(seed=1)
    swapped.reset(seed=1)
    a = np.array([0.3])
    out = native.step(a)
    out_swapped = swapped.step(a.astype(">f8"))
    assert out[0].tobytes() == out_swapped[0].tobytes() and out[1] == out_swapped[1]
    vec = _vec()
    vec.reset(seed=1)
    assert vec.step(np.full((2, 1), 0.3, dtype=">f4"))[0].dtype == np.float32


@pytest.mark.parametrize("seed", [1.5, "1", True, [1, 2, 3], [1.5, 2]])
def test_seeds_that_are_not_integers_are_refused_by_name(seed):
    vec = _vec()
    with pytest.raises(ValueError, match="seed must be an int"):
        vec.reset(seed=seed)
    if not isinstance(seed, list):
        with pytest.raises(ValueError, match="seed must be an int"):
            gym.make(BEAD).reset(seed=seed)


def test_a_refused_reset_leaves_every_generator_as_it_was():
    """A reset whose options are refused draws nothing: the next reset starts where it
    would have without the refused one."""
    vec, ref = _vec(), _vec()
    single, single_ref = gym.make(BEAD), gym.make(BEAD)
    for env in (vec, ref, single, single_ref):
        env.reset(seed=3)
    for env in (vec, single):
        for bad in ({"stat": 1}, {"state": [np.nan] * 2}, {"goal": [1e9]}):
            with pytest.raises(ValueError):
                env.reset(options=bad)
        with pytest.raises(ValueError):
            env.reset(seed=9, options={"stat": 1})  # nor is the seed taken
    assert np.array_equal(vec.reset()[0], ref.reset()[0])
    assert np.array_equal(single.reset()[0], single_ref.reset()[0])


def test_autoreset_mode_by_name_or_value_and_changed_mid_run():
    assert _vec(autoreset_mode="SAME_STEP").metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    assert _vec(autoreset_mode="SameStep").autoreset_mode == AutoresetMode.SAME_STEP
    with pytest.raises(ValueError, match="'NEXT_STEP', 'SAME_STEP'") as refused:
        _vec(autoreset_mode=AutoresetMode.DISABLED)
    assert "DISABLED" not in str(refused.value).split("got")[0]
    # a copy that ended under NEXT_STEP starts afresh on the next step after a switch to
    # SAME_STEP, instead of stepping on from its end (and paying its penalty again)
    vec = _vec(max_episode_steps=2)
    vec.reset(seed=0)
    zero = np.zeros((2, 1))
    vec.step(zero)
    assert vec.step(zero)[3].all()  # truncated: NEXT_STEP resets them on the next step
    vec.unwrapped.autoreset_mode = AutoresetMode.SAME_STEP
    assert vec.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    _, reward, term, trunc, info = vec.step(zero)
    assert (reward == 0).all() and not (term | trunc).any() and "final_obs" not in info
    assert (vec.unwrapped._rt.steps == 0).all()
