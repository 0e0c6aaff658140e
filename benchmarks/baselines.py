"""Benchmark of the agents: scores at the chosen budget, and the speed facts behind defaults.

    python benchmarks/baselines.py                 # every env: baselines, LQR, PPO (= agents.check)
    python benchmarks/baselines.py --envs Lagrange/Bicycle-v0 --results docs/data/agents.json
                                                # these envs' rows replaced, the others kept
    python benchmarks/baselines.py --speed         # torch threads; env stepping; PPO vectorisation

The scores part runs the main job (agents.check) into runs/benchmark and prints its table;
it also writes the rows, with the date and the machine of the run, as JSON (`--results`,
default runs/benchmark/results.json): the documentation site reads docs/data/agents.json,
refreshed with `--results docs/data/agents.json`. With `--envs`, only those envs are run,
and an existing results file keeps every other env's rows with the run that measured them
(`"runs"`: one record per run; each row's `"run"` is its index there).
The speed part measures what chose the defaults: PPO training throughput with one and two
torch threads, how fast SB3's DummyVecEnv of single envs steps compared with the
environment's native vector env, and PPO's env-steps/s on 16 copies through each (the
native env driven by SB3 through agents.learning.vecenv, autoresetting in the same step).
"""

from __future__ import annotations

import argparse
import csv
import datetime
import json
import os
import platform
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym
import numpy as np

import envs
from agents.check import report_dir, run_check
from agents.common import check_env_id


def ppo_rate(env_id: str, threads: int, steps: int = 8192) -> float:
    """PPO env-steps/s with `threads` torch threads (8 envs, the YAML's rollout size)."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env

    torch.set_num_threads(threads)
    model = PPO("MlpPolicy", make_vec_env(env_id, 8), n_steps=256, device="cpu", seed=0)
    start = time.perf_counter()
    model.learn(steps)
    return steps / (time.perf_counter() - start)


def stepping_rates(env_id: str, n_envs: int = 8, steps: int = 2000) -> tuple[float, float]:
    """env-steps/s of SB3's DummyVecEnv and of the native vector env (random actions)."""
    from stable_baselines3.common.env_util import make_vec_env

    actions = np.random.default_rng(0).uniform(-1, 1, (steps, n_envs) + _action_shape(env_id))
    dummy = make_vec_env(env_id, n_envs)
    dummy.reset()
    start = time.perf_counter()
    for a in actions:
        dummy.step(a)
    dummy_rate = steps * n_envs / (time.perf_counter() - start)
    native = gym.make_vec(env_id, num_envs=n_envs, vectorization_mode="vector_entry_point")
    native.reset(seed=0)
    start = time.perf_counter()
    for a in actions:
        native.step(a)
    return dummy_rate, steps * n_envs / (time.perf_counter() - start)


def ppo_vectorization_rate(env_id: str, vectorization: str, n_envs: int = 16) -> float:
    """PPO env-steps/s on `n_envs` copies made by agents.learning.vecenv ("native" or "dummy"), the
    task's PPO settings, 4 rollouts of 256 steps (the first, with compilation, not timed)."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from agents.learning import hparams
    from agents.learning.hparams import algo_kwargs
    from agents.learning.vecenv import make_sb3_vec_env

    hp = {**hparams.load("ppo", env_id), "n_steps": 256, "batch_size": 512}
    venv = VecNormalize(make_sb3_vec_env(env_id, n_envs, 0, vectorization))
    model = PPO("MlpPolicy", venv, device="cpu", seed=0, **algo_kwargs("ppo", hp, 1))
    model.learn(256 * n_envs)
    start = time.perf_counter()
    model.learn(4 * 256 * n_envs, reset_num_timesteps=False)
    return 4 * 256 * n_envs / (time.perf_counter() - start)


def _action_shape(env_id: str) -> tuple[int, ...]:
    return gym.make(env_id).action_space.shape


def commit() -> str | None:
    """The checkout's commit, so that the site can say when the code changed after the run
    (None outside a git checkout)."""
    import subprocess

    try:
        done = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True,
                              cwd=Path(__file__).resolve().parents[1], timeout=30)  # fmt: skip
    except (OSError, subprocess.TimeoutExpired):
        return None
    return done.stdout.strip() or None if done.returncode == 0 else None


def machine() -> dict:
    """What ran the benchmark: processor, cores, memory, OS and the versions that matter."""
    from importlib.metadata import PackageNotFoundError, version

    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            names = [ln.split(":", 1)[1].strip() for ln in f if ln.startswith("model name")]
        cpu = names[0] if names else cpu
    except OSError:
        pass
    try:
        memory_gib = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30
    except (ValueError, OSError, AttributeError):
        memory_gib = None
    versions = {}
    for package in ("numpy", "numba", "sympy", "gymnasium", "torch", "stable-baselines3"):
        try:
            versions[package] = version(package)
        except PackageNotFoundError:
            pass
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "memory_gib": None if memory_gib is None else round(memory_gib, 1),
        "os": platform.platform(terse=True),
        "python": platform.python_version(),
        "versions": versions,
        "threads": os.environ.get("OMP_NUM_THREADS"),
    }


def read_results(path: Path) -> dict:
    """A results file as {"runs": [meta, ...], "rows": [...]}, each row naming its run by
    index; a file of the first form (one run's meta beside its rows) is that one run."""
    data = json.loads(path.read_text(encoding="utf-8"))
    if "runs" in data:
        return data
    meta = {k: v for k, v in data.items() if k != "rows"}
    return {"runs": [meta], "rows": [{**r, "run": 0} for r in data["rows"]]}


def merge_results(old: dict, rows: list[dict], meta: dict) -> dict:
    """`old` with the rows of the envs in `rows` replaced by them (measured by `meta`); the
    runs no row refers to any more are dropped, the others keep their order."""
    measured = {r["env_id"] for r in rows}
    kept = [r for r in old["rows"] if r["env_id"] not in measured]
    used = sorted({r["run"] for r in kept})
    index = {old_i: new_i for new_i, old_i in enumerate(used)}
    runs = [old["runs"][i] for i in used] + [meta]
    kept = [{**r, "run": index[r["run"]]} for r in kept]
    return {"runs": runs, "rows": kept + [{**r, "run": len(runs) - 1} for r in rows]}


def write_results(path: Path, csv_path: Path, meta: dict, merge: bool = False) -> None:
    """The report's CSV rows as JSON, with what and where was measured (`meta`); merge:
    into the results already at `path` (if any), replacing only these envs' rows."""
    from dynamics.cache import write_atomic

    with open(csv_path, encoding="utf-8", newline="") as f:
        rows = list(csv.DictReader(f))
    if merge and path.exists():
        data = merge_results(read_results(path), rows, meta)
    else:
        data = {"runs": [meta], "rows": [{**r, "run": 0} for r in rows]}
    write_atomic(path, (json.dumps(data, indent=1) + "\n").encode("utf-8"))


def speed() -> None:
    print("| measurement | value |\n|---|---|")
    env_id = envs.ENV_IDS[0]
    for threads in (1, 2, 1, 2):
        print(
            f"| PPO on {env_id}, torch threads = {threads} | {ppo_rate(env_id, threads):.0f} "
            f"env-steps/s |",
            flush=True,
        )
    for env_id in envs.ENV_IDS:
        dummy, native = stepping_rates(env_id)
        print(
            f"| {env_id} stepping, 8 envs: DummyVecEnv / native | {dummy:.0f} / "
            f"{native:.0f} env-steps/s |",
            flush=True,
        )
    for env_id in envs.ENV_IDS:
        rates = {"native": [], "dummy": []}
        for _ in range(3):  # alternate, take medians: the shared machine's load swings
            for kind in rates:
                rates[kind].append(ppo_vectorization_rate(env_id, kind))
        native, dummy = (float(np.median(rates[k])) for k in ("native", "dummy"))
        print(
            f"| PPO on {env_id}, 16 copies: native / DummyVecEnv | {native:.0f} / {dummy:.0f} "
            f"env-steps/s ({native / dummy:.2f}x) |",
            flush=True,
        )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--speed", action="store_true", help="measure threads and env stepping")
    parser.add_argument(
        "--envs",
        nargs="+",
        metavar="ENV_ID",
        help="run only these envs; an existing results file keeps the other envs' rows",
    )
    parser.add_argument("--episodes", type=int, default=50)
    parser.add_argument(
        "--algo", help="train this everywhere (default: the algorithm each task declares)"
    )
    parser.add_argument("--timesteps", type=int, help="training budget (default: the YAML's)")
    parser.add_argument("--out", default="runs/benchmark")
    parser.add_argument(
        "--results", type=Path, help="the JSON results file (default: OUT/results.json)"
    )
    args = parser.parse_args(argv)
    if args.speed:
        speed()
        return 0
    started = datetime.datetime.now(datetime.timezone.utc)
    start = time.perf_counter()
    run_check(
        args.envs, args.algo, args.episodes, 0, args.out, args.timesteps, fresh=True,
        progress=False,
    )  # fmt: skip
    wall = time.perf_counter() - start
    args_given = sys.argv[1:] if argv is None else argv
    meta = {
        "command": " ".join(["python benchmarks/baselines.py", *args_given]),
        "started": started.isoformat(timespec="seconds"),
        "finished": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "wall_s": round(wall, 1),
        "episodes": args.episodes,
        "seed": 0,
        "machine": machine(),
        "commit": commit(),
    }
    out = Path(args.out)
    report = report_dir(out, [check_env_id(e) for e in args.envs or []], args.timesteps)
    write_results(
        args.results or out / "results.json", report / "results.csv", meta, merge=bool(args.envs)
    )
    print(f"benchmark wall time {wall:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
