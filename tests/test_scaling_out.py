"""The scaling-out recipes of docs/scaling-out.md work as written: the env factories pickle,
`gym.make("envs:...")` works in a fresh worker process, worker processes join one Optuna
study through a shared journal file, a seed sweep runs through xargs, and skrl trains on the
native vector env."""

from __future__ import annotations

import functools
import os
import pickle
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import envs

ROOT = Path(__file__).resolve().parents[1]
IDS = sorted(k for k in gym.registry if k.startswith("Lagrange/"))


def _environ() -> dict:
    return {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(ROOT)}


def test_every_lagrange_id_is_registered_and_its_factories_pickle():
    assert set(envs.ENV_IDS) <= set(IDS)
    for env_id in IDS:
        spec = pickle.loads(pickle.dumps(gym.spec(env_id)))
        assert spec.id == env_id and spec.kwargs["task"] == gym.spec(env_id).kwargs["task"]
        factory = pickle.loads(pickle.dumps(functools.partial(gym.make, f"envs:{env_id}")))
        assert factory.args == (f"envs:{env_id}",)


FRESH_WORKER = """
import sys
import gymnasium as gym
assert "envs" not in sys.modules
for env_id in sys.argv[1:]:
    env = gym.make("envs:" + env_id)  # Gymnasium imports the package named before the colon
    obs, _ = env.reset(seed=0)
    obs, reward, *_ = env.step(env.action_space.sample())
    print(env.spec.id, obs.shape[0], float(reward) == float(reward))
"""


@pytest.mark.slow  # starts a process: a few seconds
def test_gym_make_with_the_module_prefix_works_in_a_fresh_process():
    done = subprocess.run(
        [sys.executable, "-c", FRESH_WORKER, *IDS],
        env=_environ(),
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    expected = [f"{i} {gym.spec(i).make().observation_space.shape[0]} True" for i in IDS]
    assert done.stdout.split("\n")[:-1] == expected


@pytest.mark.slow  # two spawned workers
def test_async_vector_env_of_pickled_factories_steps_in_spawned_workers():
    factory = functools.partial(gym.make, "envs:Lagrange/BeadOnRod-v1")
    vec = gym.vector.AsyncVectorEnv([factory, factory], context="spawn")
    try:
        obs, _ = vec.reset(seed=0)
        obs, reward, *_ = vec.step(vec.action_space.sample())
    finally:
        vec.close()
    assert obs.shape == (2, 6) and np.isfinite(reward).all()


@pytest.mark.slow  # three workers train briefly: tens of seconds
def test_worker_processes_join_one_optuna_study_on_a_journal_file(tmp_path):
    optuna = pytest.importorskip("optuna")
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend

    journal = tmp_path / "study.log"
    command = [
        sys.executable,
        str(ROOT / "examples" / "optuna_search.py"),
        "Lagrange/BeadOnRod-v1",
        "--storage",
        str(journal),
        "--study",
        "t",
        "--trials",
        "1",
        "--timesteps",
        "512",
        "--episodes",
        "2",
        "--out",
        str(tmp_path),
    ]
    workers = [
        subprocess.Popen(
            command,
            env=_environ(),
            cwd=tmp_path,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        for _ in range(3)
    ]
    for w in workers:
        out, _ = w.communicate(timeout=600)
        assert w.returncode == 0, out
    storage = JournalStorage(JournalFileBackend(str(journal)))
    study = optuna.load_study(study_name="t", storage=storage)
    done = [t for t in study.trials if t.state == optuna.trial.TrialState.COMPLETE]
    assert len(done) == 3
    assert len({t.user_attrs["worker"] for t in done}) == 3  # three processes, one study
    assert all(np.isfinite(t.value) for t in done)
    assert sorted(t.number for t in done) == [0, 1, 2]
    for t in done:  # each trial trained through agents.train with its own hyperparameters
        assert (tmp_path / "t" / f"trial{t.number}" / "model.zip").exists()


@pytest.mark.slow  # two trainings in parallel
def test_a_seed_sweep_runs_through_xargs(tmp_path):
    script = (
        "printf '0\\n1\\n' | xargs -P 2 -I{} "
        f"{sys.executable} -m agents.train Lagrange/BeadOnRod-v1 --timesteps 256 --n-envs 2 "
        "--seed {} --run-dir sweep/seed{} --no-progress"
    )
    done = subprocess.run(
        ["bash", "-c", script],
        cwd=tmp_path,
        env=_environ(),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    for seed in (0, 1):
        assert (tmp_path / "sweep" / f"seed{seed}" / "model.zip").exists()


@pytest.mark.slow  # imports and trains skrl briefly
def test_skrl_ppo_trains_on_the_native_vector_env(tmp_path):
    pytest.importorskip("skrl")
    import logging

    logging.getLogger("skrl").setLevel(logging.WARNING)  # its handler outlives pytest's capture
    sys.path.insert(0, str(ROOT / "examples"))
    try:
        from skrl_ppo import build
    finally:
        sys.path.remove(str(ROOT / "examples"))
    trainer, env = build("Lagrange/BeadOnRod-v1", 4, 256, tmp_path)
    assert isinstance(env._env.unwrapped, envs.LagrangianVectorEnv)  # no per-copy wrapper
    trainer.train()
    memory = trainer.agents.memory
    obs = memory.get_tensor_by_name("observations").cpu().numpy()
    assert obs.shape[1:] == (4, 6) and np.isfinite(obs).all() and np.abs(obs).max() > 0
    assert list(tmp_path.glob("*/checkpoints/agent_256.pt"))
