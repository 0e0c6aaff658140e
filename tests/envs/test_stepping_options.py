"""The env options that choose how the runtime steps: integrator and num_threads."""

import gymnasium as gym
import numpy as np
import pytest

import envs


# the disk's threaded kernels are compiled for this test alone (4 s of CPU cold): -m slow
@pytest.mark.parametrize(
    "env_id",
    ["Lagrange/TwoLinkArm-v1", pytest.param("Lagrange/RollingDisk-v1", marks=pytest.mark.slow)],
)
def test_vector_env_is_bit_identical_on_one_thread_and_many(env_id):
    runs = []
    for threads in (1, 2, 3):
        vec = gym.make_vec(
            env_id, 300, vectorization_mode="vector_entry_point", num_threads=threads
        )
        obs, _ = vec.reset(seed=3)
        rng = np.random.default_rng(4)
        trace = [obs]
        for _ in range(20):
            obs, rew, term, _, info = vec.step(rng.uniform(-1, 1, vec.action_space.shape))
            trace += [obs, rew, term, info["state"]]
        runs.append(trace)
    for other in runs[1:]:
        for a, b in zip(runs[0], other):
            np.testing.assert_array_equal(a, b)


def test_integrator_option_and_task_default():
    env = gym.make("Lagrange/TwoLinkArm-v1").unwrapped
    assert (env.integrator, env.substeps) == (
        envs.tasks.arm.TASK.integrator,
        envs.tasks.arm.TASK.substeps,
    )
    env = gym.make("Lagrange/TwoLinkArm-v1", integrator="rk4", substeps=25).unwrapped
    assert env.integrator == "rk4"
    env.reset(seed=0)
    env.step(np.zeros(2))
    with pytest.raises(ValueError, match="Unknown integrator 'euler'"):
        gym.make("Lagrange/TwoLinkArm-v1", integrator="euler")
    with pytest.raises(ValueError, match="num_threads must be at least 1"):
        gym.make("Lagrange/TwoLinkArm-v1", num_threads=0)
