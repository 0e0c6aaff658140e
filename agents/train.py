"""Train a stable-baselines3 agent on an environment: `python -m agents.train ENV_ID --algo ppo`.

Hyperparameters come from agents/hyperparams/<algo>.yml (keyed by env id). A run directory
holds config.yml, checkpoints/ (atomic; `--resume` continues from the newest, keeping the
timestep count and the learning-rate schedule), model.zip and vecnormalize.pkl (atomic),
episodes.csv, eval.csv and learning_curve.png.
"""

from __future__ import annotations

import argparse
import inspect
import re
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml
from stable_baselines3 import PPO, SAC, TD3
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import CallbackList, CheckpointCallback, EvalCallback
from stable_baselines3.common.noise import NormalActionNoise
from stable_baselines3.common.utils import LinearSchedule
from stable_baselines3.common.vec_env import VecEnv, VecNormalize

from . import hparams
from .common import (
    DEFAULT_TORCH_THREADS,
    atomic_path,
    check_env_id,
    env_slug,
    non_negative_int,
    positive_int,
    set_torch_threads,
    write_text_atomic,
)
from .curves import CurveLogger
from .vecenv import VECTORIZATIONS, make_sb3_vec_env

ALGORITHMS: dict[str, type[BaseAlgorithm]] = {"ppo": PPO, "sac": SAC, "td3": TD3}
MANAGED_KEYS = ("n_timesteps", "n_envs", "policy", "normalize", "action_noise", "policy_kwargs")
CHECKPOINT_PREFIX = "rl_model"
_CHECKPOINT_RE = re.compile(rf"{CHECKPOINT_PREFIX}_(\d+)_steps\.zip$")


@dataclass
class TrainResult:
    run_dir: Path
    model_path: Path
    timesteps: int
    wall_s: float
    eval_mean: float | None
    eval_std: float | None
    success_rate: float | None
    model: BaseAlgorithm | None = field(default=None, repr=False)


def default_run_dir(env_id: str, algo: str, seed: int) -> Path:
    return Path("runs") / "train" / env_slug(env_id) / f"{algo}_seed{seed}"


# ---- hyperparameters -> SB3 keyword arguments ------------------------------------------
def _schedule(value):
    """'lin_3e-4' -> a linear decay from 3e-4 to 0 over the run (picklable, resumable)."""
    if isinstance(value, str) and value.startswith("lin_"):
        return LinearSchedule(float(value[4:]), 0.0, 1.0)
    return value


def _policy_kwargs(raw: dict | None) -> dict:
    import torch.nn as nn

    kwargs = dict(raw or {})
    if "activation_fn" in kwargs:
        name = kwargs["activation_fn"]
        table = {"tanh": nn.Tanh, "relu": nn.ReLU, "elu": nn.ELU, "leaky_relu": nn.LeakyReLU}
        if name not in table:
            raise ValueError(f"Unknown activation_fn {name!r}; known: {', '.join(table)}.")
        kwargs["activation_fn"] = table[name]
    return kwargs


def algo_kwargs(algo: str, hp: dict, action_dim: int) -> dict:
    """Keyword arguments for the algorithm's constructor from one YAML entry."""
    cls = ALGORITHMS[algo]
    kwargs = {k: _schedule(v) for k, v in hp.items() if k not in MANAGED_KEYS}
    allowed = set(inspect.signature(cls.__init__).parameters) - {"self", "policy", "env"}
    unknown = sorted(set(kwargs) - allowed)
    if unknown:
        raise ValueError(f"Unknown {algo} hyperparameter(s) {unknown} in {algo}.yml.")
    kwargs["policy_kwargs"] = _policy_kwargs(hp.get("policy_kwargs"))
    noise = hp.get("action_noise")
    if noise is not None:
        if noise.get("type") != "normal":
            raise ValueError(f"action_noise type must be 'normal', got {noise.get('type')!r}.")
        sigma = float(noise["sigma"])
        kwargs["action_noise"] = NormalActionNoise(
            np.zeros(action_dim), sigma * np.ones(action_dim)
        )
    return kwargs


# ---- environments ----------------------------------------------------------------------
def _normalize_kwargs(hp: dict) -> dict | None:
    normalize = hp.get("normalize", False)
    if normalize is True:
        return {}
    if not normalize:
        return None
    return dict(normalize)


def make_envs(env_id: str, hp: dict, n_envs: int, seed: int, vectorization: str, eval_envs: int):
    """Training and evaluation VecEnvs, both wrapped in VecNormalize if the YAML asks."""
    train_env = make_sb3_vec_env(env_id, n_envs, seed, vectorization)
    eval_env = make_sb3_vec_env(env_id, eval_envs, seed + 10_000, vectorization)
    norm = _normalize_kwargs(hp)
    if norm is not None:
        train_env = VecNormalize(train_env, **norm)
        eval_env = VecNormalize(eval_env, **{**norm, "training": False, "norm_reward": False})
    return train_env, eval_env


# ---- checkpoints -------------------------------------------------------------------------
class AtomicCheckpoint(CheckpointCallback):
    """SB3's CheckpointCallback saving at the first rollout boundary after every
    `save_freq` calls, every file written atomically, the curves flushed with it (so they
    agree with the checkpoint), and only the newest checkpoint kept."""

    def __init__(self, save_freq: int, save_path: Path, curves: CurveLogger):
        super().__init__(
            save_freq,
            str(save_path),
            name_prefix=CHECKPOINT_PREFIX,
            save_replay_buffer=True,
            save_vecnormalize=True,
        )
        self.curves = curves
        self._due = False

    def _on_step(self) -> bool:
        self._due = self._due or self.n_calls % self.save_freq == 0
        return True

    def _on_rollout_start(self) -> None:
        # after the previous rollout's gradient steps: the weights, the timestep count and
        # (PPO) the empty rollout buffer agree, so a resumed run continues exactly here
        if getattr(self, "_due", False):
            self.save()
            self._due = False

    def save(self) -> Path:
        """Write a checkpoint at the current timestep (companions first, model last)."""
        vecnorm = self.model.get_vec_normalize_env()
        if vecnorm is not None:
            with atomic_path(self._checkpoint_path("vecnormalize_", "pkl")) as tmp:
                vecnorm.save(tmp)
        if getattr(self.model, "replay_buffer", None) is not None:
            with atomic_path(self._checkpoint_path("replay_buffer_", "pkl")) as tmp:
                self.model.save_replay_buffer(tmp)
        self.curves.flush()
        path = Path(self._checkpoint_path(extension="zip"))
        with atomic_path(path) as tmp:
            self.model.save(tmp)
        for old in Path(self.save_path).glob(f"{CHECKPOINT_PREFIX}_*"):
            if not old.name.endswith(f"_{self.num_timesteps}_steps{old.suffix}"):
                old.unlink(missing_ok=True)
        return path


def latest_checkpoint(directory: Path) -> tuple[int, Path] | None:
    """(timesteps, model path) of the newest checkpoint in `directory`, if any."""
    found = []
    for path in directory.glob(f"{CHECKPOINT_PREFIX}_*_steps.zip"):
        match = _CHECKPOINT_RE.search(path.name)
        if match:
            found.append((int(match.group(1)), path))
    return max(found) if found else None


def _companion(directory: Path, kind: str, steps: int) -> Path:
    return directory / f"{CHECKPOINT_PREFIX}_{kind}_{steps}_steps.pkl"


# ---- the work ----------------------------------------------------------------------------
def train(
    env_id: str,
    algo: str = "ppo",
    timesteps: int | None = None,
    seed: int = 0,
    n_envs: int | None = None,
    run_dir: str | Path | None = None,
    resume: bool = False,
    eval_freq: int | None = None,
    eval_episodes: int = 10,
    checkpoint_freq: int | None = None,
    vectorization: str = "auto",
    progress: bool = True,
    threads: int = DEFAULT_TORCH_THREADS,
    verbose: int = 0,
) -> TrainResult:
    """Train `algo` on `env_id`; return where the model is and how it evaluated.

    timesteps, n_envs: override the YAML's n_timesteps / n_envs. eval_freq and
    checkpoint_freq count environment steps (default: total/10 but at least 2000,
    and total/5)."""
    env_id = check_env_id(env_id)
    hp = hparams.load(algo, env_id)
    total = int(timesteps if timesteps is not None else hp["n_timesteps"])
    n_envs = int(n_envs if n_envs is not None else hp.get("n_envs", 1))
    for name, value in (("timesteps", total), ("n_envs", n_envs), ("eval_episodes", eval_episodes)):
        if value < 1:
            raise ValueError(f"{name} must be a positive integer, got {value}.")
    if vectorization not in VECTORIZATIONS:
        raise ValueError(f"vectorization must be one of {VECTORIZATIONS}, got {vectorization!r}.")
    set_torch_threads(threads)
    run_dir = Path(run_dir) if run_dir is not None else default_run_dir(env_id, algo, seed)
    ckpt_dir = run_dir / "checkpoints"
    found = latest_checkpoint(ckpt_dir) if resume else None
    if resume and found is None:
        print(f"No checkpoint in {ckpt_dir}; starting a fresh run.", file=sys.stderr)
    if found is None:  # a fresh run: an older run's checkpoints must not be resumed later
        for old in ckpt_dir.glob(f"{CHECKPOINT_PREFIX}_*"):
            old.unlink()
    write_text_atomic(
        run_dir / "config.yml",
        yaml.safe_dump(
            {
                "env_id": env_id,
                "algo": algo,
                "seed": seed,
                "n_timesteps": total,
                "n_envs": n_envs,
                "vectorization": vectorization,
                "hyperparams": hp,
            },
            sort_keys=False,
        ),
    )

    train_env, eval_env = make_envs(env_id, hp, n_envs, seed, vectorization, min(eval_episodes, 5))
    curves = CurveLogger(run_dir, f"{algo.upper()} on {env_id}", found[0] if found else None)
    model = _build_or_load(algo, hp, train_env, seed, found, ckpt_dir, verbose)
    eval_freq = eval_freq or max(total // 10, 2000)
    checkpoint_freq = checkpoint_freq or max(total // 5, 1)
    checkpoint = AtomicCheckpoint(max(checkpoint_freq // n_envs, 1), ckpt_dir, curves)
    evaluation = EvalCallback(
        eval_env,
        n_eval_episodes=eval_episodes,
        eval_freq=max(eval_freq // n_envs, 1),
        deterministic=True,
        callback_after_eval=curves.after_eval,
        log_path=str(curves.staging_dir),
        verbose=0,
    )
    remaining = total - model.num_timesteps
    start = time.perf_counter()
    if remaining > 0:
        model.learn(
            remaining,
            callback=CallbackList([curves, evaluation, checkpoint]),
            reset_num_timesteps=found is None,
            progress_bar=progress,
        )
        checkpoint.save()
    wall = time.perf_counter() - start
    model_path = save_final(model, run_dir)
    curves.flush()
    if curves.staging_dir.exists() and not any(curves.staging_dir.iterdir()):
        curves.staging_dir.rmdir()
    train_env.close()
    eval_env.close()
    last = curves.evals[-1] if curves.evals else {}
    success = last.get("success_rate", "")
    return TrainResult(
        run_dir=run_dir,
        model_path=model_path,
        timesteps=model.num_timesteps,
        wall_s=wall,
        eval_mean=float(last["mean_return"]) if last else None,
        eval_std=float(last["std_return"]) if last else None,
        success_rate=float(success) if success != "" else None,
        model=model,
    )


def _build_or_load(algo, hp, env: VecEnv, seed, found, ckpt_dir: Path, verbose) -> BaseAlgorithm:
    cls = ALGORITHMS[algo]
    if found is None:
        kwargs = algo_kwargs(algo, hp, int(np.prod(env.action_space.shape)))
        return cls(
            hp.get("policy", "MlpPolicy"), env, seed=seed, device="cpu", verbose=verbose, **kwargs
        )
    steps, path = found
    stats = _companion(ckpt_dir, "vecnormalize", steps)
    if isinstance(env, VecNormalize):
        if not stats.exists():
            raise FileNotFoundError(f"Checkpoint {path.name} has no normalisation statistics.")
        env = VecNormalize.load(str(stats), env.venv)
    model = cls.load(path, env=env, device="cpu")
    buffer = _companion(ckpt_dir, "replay_buffer", steps)
    if hasattr(model, "replay_buffer") and buffer.exists():
        model.load_replay_buffer(buffer)
    print(f"Resuming from {path} at {model.num_timesteps} timesteps.", file=sys.stderr)
    return model


def save_final(model: BaseAlgorithm, run_dir: Path) -> Path:
    """model.zip (and vecnormalize.pkl if the env is normalised), each written atomically."""
    vecnorm = model.get_vec_normalize_env()
    if vecnorm is not None:
        with atomic_path(run_dir / "vecnormalize.pkl") as tmp:
            vecnorm.save(tmp)
    path = run_dir / "model.zip"
    with atomic_path(path) as tmp:
        model.save(tmp)
    return path


# ---- command line ------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m agents.train",
        description="Train a stable-baselines3 agent with the per-environment hyperparameters "
        "of agents/hyperparams/<algo>.yml. Writes a run directory with checkpoints, the "
        "model, normalisation statistics and learning curves (CSV and PNG).",
    )
    parser.add_argument("env_id", help="Gymnasium id, e.g. Lagrange/TwoLinkArm-v0")
    parser.add_argument("--algo", default="ppo", help=f"one of {', '.join(ALGORITHMS)}")
    parser.add_argument("--timesteps", type=positive_int, help="budget (default: YAML n_timesteps)")
    parser.add_argument("--seed", type=non_negative_int, default=0)
    parser.add_argument("--n-envs", type=positive_int, help="parallel envs (default: YAML n_envs)")
    parser.add_argument("--run-dir", help="output directory (default runs/train/ENV/ALGO_seedS)")
    parser.add_argument("--resume", action="store_true", help="continue from the newest checkpoint")
    parser.add_argument("--eval-freq", type=positive_int, help="env steps between evaluations")
    parser.add_argument("--eval-episodes", type=positive_int, default=10)
    parser.add_argument(
        "--checkpoint-freq", type=positive_int, help="env steps between checkpoints"
    )
    parser.add_argument(
        "--vectorization",
        choices=VECTORIZATIONS,
        default="auto",
        help="native: the env's batched vector_entry_point; dummy: SB3 DummyVecEnv",
    )
    parser.add_argument(
        "--threads",
        type=positive_int,
        default=DEFAULT_TORCH_THREADS,
        help="torch threads (1 is fastest for these small networks)",
    )
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.algo not in ALGORITHMS:
        parser.error(f"unknown algorithm {args.algo!r}; choose from {', '.join(ALGORITHMS)}")
    try:
        env_id = check_env_id(args.env_id)
    except ValueError as exc:
        parser.error(str(exc))
    result = train(
        env_id,
        args.algo,
        args.timesteps,
        args.seed,
        args.n_envs,
        args.run_dir,
        args.resume,
        args.eval_freq,
        args.eval_episodes,
        args.checkpoint_freq,
        args.vectorization,
        progress=not args.no_progress,
        threads=args.threads,
    )
    rate = "" if result.success_rate is None else f", success {result.success_rate:.0%}"
    evaluation = (
        "no evaluation"
        if result.eval_mean is None
        else f"last evaluation {result.eval_mean:.1f} +- {result.eval_std:.1f}{rate}"
    )
    print(
        f"{args.algo} on {env_id}: {result.timesteps} steps in {result.wall_s:.0f} s, "
        f"{evaluation}. Model: {result.model_path}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
