"""Train a stable-baselines3 agent on an environment: `python -m agents.train ENV_ID --algo ppo`.

Hyperparameters come from agents/hyperparams/<algo>.yml (keyed by env id), overridden by a
file of the same format given with `--hyperparams`. A run directory holds config.yml, checkpoints/
(atomic; `--resume` continues from the newest, keeping the timestep count, the
learning-rate schedule and the evaluation schedule), model.zip and vecnormalize.pkl (atomic),
episodes.csv, eval.csv, evaluations.npz and learning_curve.png.

Ctrl-C (SIGINT) or SIGTERM stops training at the next environment step and saves the model,
its normalisation statistics and a checkpoint before exiting with 128 + the signal number
(130 for Ctrl-C); a second signal stops at once without saving. A directory that holds an
earlier run is only trained into with `--resume` (continue it) or `--overwrite` (start
afresh); only one process trains into a directory at a time.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import inspect
import re
import shlex
import signal
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml
from stable_baselines3 import PPO, SAC, TD3
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import (
    BaseCallback,
    CallbackList,
    CheckpointCallback,
    EvalCallback,
    ProgressBarCallback,
)
from stable_baselines3.common.noise import NormalActionNoise
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.save_util import save_to_pkl
from stable_baselines3.common.utils import LinearSchedule
from stable_baselines3.common.vec_env import VecEnv, VecNormalize

from . import hparams
from .common import (
    DEFAULT_TORCH_THREADS,
    UserError,
    atomic_path,
    check_env_id,
    env_slug,
    non_negative_int,
    positive_int,
    set_torch_threads,
    write_atomic,
)
from .curves import CurveLogger
from .handover import HandOverVecEnv, handover_options
from .vecenv import VECTORIZATIONS, make_sb3_vec_env

try:  # one training process per run directory (POSIX advisory lock)
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None

ALGORITHMS: dict[str, type[BaseAlgorithm]] = {"ppo": PPO, "sac": SAC, "td3": TD3}
MANAGED_KEYS = (
    "n_timesteps",
    "n_envs",
    "policy",
    "normalize",
    "action_noise",
    "policy_kwargs",
    "handover",
)
CHECKPOINT_PREFIX = "rl_model"
_CHECKPOINT_RE = re.compile(rf"{CHECKPOINT_PREFIX}_(\d+)_steps\.zip$")
# every file a run writes: checkpoints/ holds the CHECKPOINT_FILE ones, the run directory these
CHECKPOINT_FILE = re.compile(rf"{CHECKPOINT_PREFIX}_(?:[a-z_]+_)?\d+_steps\.(?:zip|pkl)")
RUN_FILES = (
    "config.yml",
    "model.zip",
    "vecnormalize.pkl",
    "episodes.csv",
    "eval.csv",
    "evaluations.npz",
    "learning_curve.png",
)
# the temporary name `atomic_path` gives FILE: ".FILE.<8 random characters><FILE's suffix>"
_TEMPORARY = re.compile(r"\.(?P<name>.+)\.[a-z0-9_]{8}(?P<suffix>\.[A-Za-z0-9]+)")


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


class TrainingInterrupted(KeyboardInterrupt):
    """Training stopped on a signal after saving; `result` says what was saved and
    `exit_code` is the shell's 128 + signal number (130 for Ctrl-C)."""

    def __init__(self, result: TrainResult, signum: int):
        super().__init__(f"training interrupted by {signal.Signals(signum).name}")
        self.result = result
        self.signum = signum
        self.exit_code = 128 + signum


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


def algo_kwargs(algo: str, hp: dict, action_dim: int, source: str | None = None) -> dict:
    """Keyword arguments for the algorithm's constructor from one YAML entry (`source`
    names the file in error messages; default <algo>.yml)."""
    cls = ALGORITHMS[algo]
    kwargs = {k: _schedule(v) for k, v in hp.items() if k not in MANAGED_KEYS}
    allowed = set(inspect.signature(cls.__init__).parameters) - {"self", "policy", "env"}
    unknown = sorted(set(kwargs) - allowed)
    if unknown:
        where = source or f"{algo}.yml"
        raise ValueError(f"Unknown {algo} hyperparameter(s) {unknown} in {where}.")
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


def load_hyperparams(algo: str, env_id: str, path: str | Path | None = None) -> dict:
    """The YAML entry for (algo, env_id): the packaged one, or `path`'s; checked against the
    algorithm's constructor, every problem a UserError."""
    if algo not in ALGORITHMS:
        raise UserError(f"Unknown algorithm {algo!r}; choose from {', '.join(ALGORITHMS)}.")
    if path is not None and not Path(path).is_file():
        raise UserError(f"Hyperparameter file {path} does not exist.")
    try:
        hp = hparams.load(algo, env_id) if path is None else hparams.load(algo, env_id, path=path)
        algo_kwargs(algo, hp, 1, source=None if path is None else str(path))
        handover_options(hp.get("handover"))
    except (ValueError, TypeError, AttributeError, yaml.YAMLError) as exc:
        where = f" ({path})" if path is not None and str(path) not in str(exc) else ""
        raise UserError(f"{' '.join(str(exc).split())}{where}") from exc
    return hp


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
    handover = handover_options(hp.get("handover"))
    if handover is not None:  # the agent learns in the closed loop it will act in
        gamma = float(hp.get("gamma", 0.99))
        # the agent learns to aim at the level set; it is evaluated as it will act, with
        # the verified states added (agents.handover)
        check = {k: handover[k] for k in ("verify", "verify_level")}
        train_env = HandOverVecEnv(train_env, handover["level"], handover["shaping"], gamma)
        eval_env = HandOverVecEnv(eval_env, handover["level"], **check)
    norm = _normalize_kwargs(hp)
    if norm is not None:
        train_env = VecNormalize(train_env, **norm)
        eval_env = VecNormalize(eval_env, **{**norm, "training": False, "norm_reward": False})
    return train_env, eval_env


# ---- the run directory -------------------------------------------------------------------
@contextlib.contextmanager
def exclusive(run_dir: Path):
    """Hold `run_dir` for one training process (a lock on run_dir/.lock, released when the
    process ends however it ends); a second process gets a UserError."""
    run_dir.mkdir(parents=True, exist_ok=True)
    if fcntl is None:  # pragma: no cover
        yield
        return
    with open(run_dir / ".lock", "w") as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise UserError(
                f"Another process is training into {run_dir}; wait for it or choose "
                "another --run-dir."
            ) from None
        yield


def is_stale_temporary(name: str) -> bool:
    """True for the temporary name `atomic_path` gives one of this program's files (a
    process killed while writing leaves it behind; the lock says no writer is alive)."""
    match = _TEMPORARY.fullmatch(name)
    if match is None or not match["name"].endswith(match["suffix"]):
        return False
    return match["name"] in RUN_FILES or CHECKPOINT_FILE.fullmatch(match["name"]) is not None


def remove_stale_temporaries(run_dir: Path) -> list[Path]:
    """Delete what killed writers left in `run_dir`, checkpoints/ and .staging/ (only
    names this program writes); return the deleted paths."""
    stale = [
        path
        for directory in (run_dir, run_dir / "checkpoints")
        if directory.is_dir()
        for path in directory.iterdir()
        if path.is_file() and is_stale_temporary(path.name)
    ]
    stale += [p for p in [run_dir / ".staging" / "evaluations.npz"] if p.exists()]
    for path in stale:
        path.unlink()
    return stale


def _run_files(run_dir: Path) -> list[Path]:
    files = [run_dir / name for name in RUN_FILES if (run_dir / name).exists()]
    ckpt_dir = run_dir / "checkpoints"
    if ckpt_dir.is_dir():
        files += [p for p in ckpt_dir.iterdir() if CHECKPOINT_FILE.fullmatch(p.name)]
    return files


def _holds_a_run(run_dir: Path) -> bool:
    return any(p.name != "config.yml" for p in _run_files(run_dir))


def prepare_run_dir(
    run_dir: Path, env_id: str, algo: str, resume: bool, overwrite: bool
) -> tuple[int, Path] | None:
    """The checkpoint to resume from, or None for a fresh run (after removing an earlier
    run's files when `overwrite`). An earlier run is never replaced unasked."""
    if resume and overwrite:
        raise UserError("Give --resume (continue the run) or --overwrite (replace it), not both.")
    found = latest_checkpoint(run_dir / "checkpoints")
    if resume and found is not None:
        _check_same_run(run_dir, env_id, algo)
        return found
    if _holds_a_run(run_dir) and not overwrite:
        if resume:
            raise UserError(
                f"{run_dir} holds an earlier run but no checkpoint to resume from; pass "
                "--overwrite to replace it, or choose another --run-dir."
            )
        raise UserError(
            f"{run_dir} holds an earlier run; pass --resume to continue it or --overwrite "
            "to replace it, or choose another --run-dir."
        )
    if resume:
        print(f"No checkpoint in {run_dir / 'checkpoints'}; starting a fresh run.", file=sys.stderr)
    for path in _run_files(run_dir):  # a later --resume must not pick up an older run
        path.unlink()
    return None


def _check_same_run(run_dir: Path, env_id: str, algo: str) -> None:
    config = run_dir / "config.yml"
    if not config.exists():
        return
    earlier = yaml.safe_load(config.read_text(encoding="utf-8")) or {}
    if (earlier.get("env_id"), earlier.get("algo")) != (env_id, algo):
        raise UserError(
            f"{run_dir} holds a {earlier.get('algo')} run on {earlier.get('env_id')}, "
            f"not {algo} on {env_id}; resume it with those, or choose another --run-dir."
        )


# ---- checkpoints -------------------------------------------------------------------------
def _crossed(before: int, now: int, every: int) -> bool:
    """True when the timestep count passed a multiple of `every` going from before to now."""
    return now // every > before // every


class AtomicCheckpoint(CheckpointCallback):
    """SB3's CheckpointCallback saving at the first rollout boundary after the run's
    timestep count passes a multiple of `every` (counted over the whole run, so a resumed
    run checkpoints where an uninterrupted one would), every file written atomically, the
    curves flushed with it (so they agree with the checkpoint), the replay buffer without
    its empty capacity, and only the newest checkpoint kept."""

    def __init__(self, every: int, save_path: Path, curves: CurveLogger):
        super().__init__(
            every,
            str(save_path),
            name_prefix=CHECKPOINT_PREFIX,
            save_replay_buffer=True,
            save_vecnormalize=True,
        )
        self.every = every
        self.curves = curves
        self._due = False
        self._seen = 0

    def _on_training_start(self) -> None:
        self._seen = self.num_timesteps

    def _on_step(self) -> bool:
        self._due = self._due or _crossed(self._seen, self.num_timesteps, self.every)
        self._seen = self.num_timesteps
        return True

    def _on_rollout_start(self) -> None:
        # after the previous rollout's gradient steps: the weights, the timestep count and
        # (PPO) the empty rollout buffer agree, so a resumed run continues exactly here
        if self._due:
            self.save()
            self._due = False

    def save(self) -> Path:
        """Write a checkpoint at the model's timestep (companions first, model last)."""
        self.num_timesteps = self.model.num_timesteps  # after an interrupt it was rolled back
        vecnorm = self.model.get_vec_normalize_env()
        if vecnorm is not None:
            with atomic_path(self._checkpoint_path("vecnormalize_", "pkl")) as tmp:
                vecnorm.save(tmp)
        if getattr(self.model, "replay_buffer", None) is not None:
            with atomic_path(self._checkpoint_path("replay_buffer_", "pkl")) as tmp:
                save_replay_buffer(self.model, tmp)
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


def save_replay_buffer(model: BaseAlgorithm, path: str | Path) -> None:
    """Pickle the model's replay buffer without the unused part of its capacity.

    SB3's `save_replay_buffer` pickles all `buffer_size` rows (40 MB for Pendulum's 1e6,
    however few are filled); this pickles a shallow copy whose arrays are cut to the filled
    rows and records which, so `load_replay_buffer` restores the capacity."""
    buffer = model.replay_buffer
    if buffer.full:
        save_to_pkl(path, buffer)
        return
    # with optimize_memory_usage the next observation of the newest step is row pos
    extra = int(getattr(buffer, "optimize_memory_usage", False))
    keep = min(buffer.pos + extra, buffer.buffer_size)
    trimmed = copy.copy(buffer)
    names = []
    for name, value in vars(buffer).items():
        cut = _cut_rows(value, buffer.buffer_size, keep)
        if cut is not None:
            setattr(trimmed, name, cut)
            names.append(name)
    trimmed.trimmed_fields = names
    save_to_pkl(path, trimmed)


def load_replay_buffer(model: BaseAlgorithm, path: str | Path) -> None:
    """Load a buffer written by `save_replay_buffer` (or SB3's) into `model` at full capacity."""
    model.load_replay_buffer(path)
    buffer = model.replay_buffer
    for name in vars(buffer).pop("trimmed_fields", ()):
        setattr(buffer, name, _regrow_rows(getattr(buffer, name), buffer.buffer_size))


def _cut_rows(value, rows: int, keep: int):
    if isinstance(value, np.ndarray) and value.ndim >= 1 and value.shape[0] == rows:
        return value[:keep]  # a view: pickling writes only its rows
    if (
        isinstance(value, dict)
        and value
        and all(
            isinstance(v, np.ndarray) and v.ndim >= 1 and v.shape[0] == rows for v in value.values()
        )
    ):
        return {k: v[:keep] for k, v in value.items()}
    return None


def _regrow_rows(value, rows: int):
    if isinstance(value, dict):
        return {k: _regrow_rows(v, rows) for k, v in value.items()}
    full = np.zeros((rows, *value.shape[1:]), dtype=value.dtype)
    full[: len(value)] = value
    return full


# ---- callbacks ---------------------------------------------------------------------------
class ScheduledEval(EvalCallback):
    """SB3's EvalCallback, run at the first step after the run's timestep count passes each
    multiple of `every`. SB3 counts its own calls, which restart at zero when a run is
    resumed; counting the model's timesteps puts a resumed run's evaluations on the same
    steps as an uninterrupted run's."""

    def __init__(self, eval_env: VecEnv, every: int, **kwargs):
        super().__init__(eval_env, eval_freq=1, **kwargs)  # every call that reaches it
        self.every = every
        self._seen = 0

    def restore(self, npz: Path, up_to: int) -> None:
        """Continue the evaluations.npz of the run being resumed (rows up to `up_to`)."""
        if not npz.exists():
            return
        with np.load(npz) as data:
            if data["results"].ndim != 2 or data["results"].shape[1] != self.n_eval_episodes:
                return  # another episode count: SB3 could not stack the two in one file
            keep = np.asarray(data["timesteps"]) <= up_to
            self.evaluations_timesteps = [int(t) for t in data["timesteps"][keep]]
            self.evaluations_results = [list(r) for r in data["results"][keep]]
            self.evaluations_length = [list(n) for n in data["ep_lengths"][keep]]
            if "successes" in data and len(data["successes"]) == len(keep):
                self.evaluations_successes = [list(s) for s in data["successes"][keep]]

    def _on_training_start(self) -> None:
        self._seen = self.num_timesteps

    def _on_step(self) -> bool:
        before, self._seen = self._seen, self.num_timesteps
        if not _crossed(before, self.num_timesteps, self.every):
            return True
        return super()._on_step()


class GracefulStop(BaseCallback):
    """Ends training cleanly on SIGINT (Ctrl-C) or SIGTERM; use as a context manager around
    `learn` and the saves after it.

    The handler only records the signal; the next step returns False, which SB3 takes as
    "stop learning", and the caller saves. Python's default, raising KeyboardInterrupt from
    wherever the main thread happens to be, loses the work (learn() unwinds past every save)
    or the signal (raised inside a finaliser such as the llvmlite objects numba frees while
    it loads its kernels, it is printed as "Exception ignored" and training goes on). A
    second signal raises KeyboardInterrupt at once, without saving. Handlers are installed
    only in the main thread and only over the default ones (a signal the parent process
    told us to ignore stays ignored).

    `consistent_timesteps` is the count at the start of the rollout in progress: the last
    point whose experience the weights hold (the partial rollout is dropped)."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self):
        super().__init__()
        self.signum: int | None = None
        self.consistent_timesteps = 0
        self._previous: dict = {}

    def __enter__(self) -> GracefulStop:
        if threading.current_thread() is threading.main_thread():
            for sig in self.SIGNALS:
                if signal.getsignal(sig) in (signal.default_int_handler, signal.SIG_DFL):
                    self._previous[sig] = signal.signal(sig, self._handle)
        return self

    def __exit__(self, *exc) -> None:
        while self._previous:
            sig, handler = self._previous.popitem()
            signal.signal(sig, handler)

    def _handle(self, signum: int, frame) -> None:
        if self.signum is not None:
            self.__exit__()
            raise KeyboardInterrupt
        self.signum = signum
        print(
            f"\n{signal.Signals(signum).name}: stopping and saving "
            "(send it again to stop at once without saving).",
            file=sys.stderr,
        )

    def _on_training_start(self) -> None:
        self.consistent_timesteps = self.model.num_timesteps

    def _on_rollout_start(self) -> None:
        self.consistent_timesteps = self.model.num_timesteps

    def _on_step(self) -> bool:
        return self.signum is None


class _StopFirst(CallbackList):
    """CallbackList that stops calling the rest once one asks to stop (so an evaluation or
    a log row is not made for a step that an interrupt drops)."""

    def _on_step(self) -> bool:
        return all(callback.on_step() for callback in self.callbacks)


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
    hyperparams: str | Path | None = None,
    overwrite: bool = False,
    allow_missing_buffer: bool = False,
) -> TrainResult:
    """Train `algo` on `env_id`; return where the model is and how it evaluated.

    timesteps, n_envs: override the YAML's n_timesteps / n_envs. hyperparams: a YAML file
    in the format of agents/hyperparams/<algo>.yml whose entries override the packaged ones.
    eval_freq and checkpoint_freq count environment steps over the whole run (default:
    total/10 but at least 2000, and total/5). A directory holding an earlier run needs
    `resume` (continue from its newest checkpoint) or `overwrite` (delete it, start afresh);
    an off-policy checkpoint without its replay buffer is refused unless
    `allow_missing_buffer` (the run then goes on with an empty buffer).

    Raises UserError for problems with the arguments, the hyperparameters or the run
    directory (before anything is written), and TrainingInterrupted after saving when
    SIGINT or SIGTERM stopped the run."""
    env_id = check_env_id(env_id)
    hp = load_hyperparams(algo, env_id, hyperparams)
    total = int(timesteps if timesteps is not None else hp["n_timesteps"])
    n_envs = int(n_envs if n_envs is not None else hp.get("n_envs", 1))
    for name, value in (("timesteps", total), ("n_envs", n_envs), ("eval_episodes", eval_episodes)):
        if value < 1:
            raise UserError(f"{name} must be a positive integer, got {value}.")
    if vectorization not in VECTORIZATIONS:
        raise UserError(f"vectorization must be one of {VECTORIZATIONS}, got {vectorization!r}.")
    set_torch_threads(threads)
    run_dir = Path(run_dir) if run_dir is not None else default_run_dir(env_id, algo, seed)
    with exclusive(run_dir):
        remove_stale_temporaries(run_dir)
        found = prepare_run_dir(run_dir, env_id, algo, resume, overwrite)
        config = {
            "env_id": env_id,
            "algo": algo,
            "seed": seed,
            "n_timesteps": total,
            "n_envs": n_envs,
            "vectorization": vectorization,
            "hyperparams_file": None if hyperparams is None else str(hyperparams),
            "hyperparams": hp,
        }
        write_atomic(run_dir / "config.yml", yaml.safe_dump(config, sort_keys=False))
        options = dict(
            eval_freq=eval_freq or max(total // 10, 2000),
            eval_episodes=eval_episodes,
            checkpoint_freq=checkpoint_freq or max(total // 5, 1),
            progress=progress,
            verbose=verbose,
            allow_missing_buffer=allow_missing_buffer,
        )
        return _run(env_id, algo, hp, total, n_envs, seed, vectorization, run_dir, found, **options)


def _run(env_id, algo, hp, total, n_envs, seed, vectorization, run_dir, found, **o) -> TrainResult:
    """Build (or load) the model, learn up to `total` timesteps, save; see `train`."""
    ckpt_dir = run_dir / "checkpoints"
    eval_envs = min(o["eval_episodes"], 5)
    train_env, eval_env = make_envs(env_id, hp, n_envs, seed, vectorization, eval_envs)
    stop = GracefulStop()
    try:
        model = _build_or_load(
            algo, hp, train_env, seed, found, ckpt_dir, o["verbose"], o["allow_missing_buffer"]
        )
        curves = CurveLogger(run_dir, f"{algo.upper()} on {env_id}", found[0] if found else None)
        checkpoint = AtomicCheckpoint(o["checkpoint_freq"], ckpt_dir, curves)
        evaluation = ScheduledEval(
            eval_env,
            o["eval_freq"],
            n_eval_episodes=o["eval_episodes"],
            deterministic=True,
            callback_after_eval=curves.after_eval,
            log_path=str(curves.staging_dir),
            verbose=0,
        )
        if found is not None:
            evaluation.restore(run_dir / "evaluations.npz", found[0])
        start = time.perf_counter()
        learning = model.num_timesteps < total  # else a finished run, resumed
        with stop:  # from here to the last save a signal stops and saves instead of killing
            if learning:
                callbacks = [stop, curves, evaluation, checkpoint]
                _learn(model, total, callbacks, fresh=found is None, progress=o["progress"])
            if stop.signum is not None:  # keep what the weights have learnt from, no more
                model.num_timesteps = stop.consistent_timesteps
                curves.truncate(model.num_timesteps)
            if learning:
                checkpoint.save()
            model_path = save_final(model, run_dir)
            curves.close()
        wall = time.perf_counter() - start
    finally:
        train_env.close()
        eval_env.close()
    last = curves.evals[-1] if curves.evals else {}
    success = last.get("success_rate", "")
    result = TrainResult(
        run_dir=run_dir,
        model_path=model_path,
        timesteps=model.num_timesteps,
        wall_s=wall,
        eval_mean=float(last["mean_return"]) if last else None,
        eval_std=float(last["std_return"]) if last else None,
        success_rate=float(success) if success != "" else None,
        model=model,
    )
    if stop.signum is not None:
        raise TrainingInterrupted(result, stop.signum)
    return result


def _learn(model: BaseAlgorithm, total: int, callbacks: list, fresh: bool, progress: bool):
    # our own progress bar, so that it is closed (and its refresh thread stopped) however
    # learn() ends; SB3's (progress_bar=True) is closed only when training ends normally
    bar = ProgressBarCallback() if progress else None
    try:
        model.learn(
            total - model.num_timesteps,
            callback=_StopFirst(callbacks + ([bar] if bar else [])),
            reset_num_timesteps=fresh,
        )
    finally:
        if bar is not None and hasattr(bar, "pbar"):
            bar.pbar.close()


def _build_or_load(
    algo, hp, env: VecEnv, seed, found, ckpt_dir: Path, verbose, allow_missing_buffer=False
) -> BaseAlgorithm:
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
            raise UserError(
                f"Checkpoint {path} has no normalisation statistics ({stats.name}); "
                "it cannot be resumed (--overwrite starts afresh)."
            )
        env = VecNormalize.load(str(stats), env.venv)
    buffer = _companion(ckpt_dir, "replay_buffer", steps)
    off_policy = issubclass(cls, OffPolicyAlgorithm)
    if off_policy and not buffer.exists():
        if not allow_missing_buffer:
            raise UserError(
                f"Checkpoint {path} has no replay buffer ({buffer.name}); resuming would "
                "start from an empty one. Pass --allow-missing-buffer to accept that."
            )
        print(f"No replay buffer for {path.name}: resuming with an empty one.", file=sys.stderr)
    model = cls.load(path, env=env, device="cpu")
    if off_policy and buffer.exists():
        load_replay_buffer(model, buffer)
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
        "model, normalisation statistics and learning curves (CSV and PNG). Ctrl-C saves "
        "the model and a checkpoint, then exits with status 130; --resume continues.",
    )
    parser.add_argument("env_id", help="Gymnasium id, e.g. Lagrange/TwoLinkArm-v0")
    parser.add_argument("--algo", default="ppo", help=f"one of {', '.join(ALGORITHMS)}")
    parser.add_argument("--timesteps", type=positive_int, help="budget (default: YAML n_timesteps)")
    parser.add_argument("--seed", type=non_negative_int, default=0)
    parser.add_argument("--n-envs", type=positive_int, help="parallel envs (default: YAML n_envs)")
    parser.add_argument(
        "--hyperparams",
        metavar="FILE",
        help="YAML file in the format of agents/hyperparams/<algo>.yml; its entries override",
    )
    parser.add_argument("--run-dir", help="output directory (default runs/train/ENV/ALGO_seedS)")
    parser.add_argument("--resume", action="store_true", help="continue from the newest checkpoint")
    parser.add_argument(
        "--overwrite",
        action="store_true",
        help="start afresh in a run directory that holds an earlier run (deletes its files)",
    )
    parser.add_argument(
        "--allow-missing-buffer",
        action="store_true",
        help="resume a SAC/TD3 checkpoint whose replay buffer is missing with an empty buffer",
    )
    parser.add_argument(
        "--eval-freq", type=positive_int, help="env steps between evaluations (whole run)"
    )
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
    """Exit status: 0 done, 2 a usage error (one line on stderr), 128 + N stopped by signal N
    (130 for Ctrl-C) after saving, or 130 when interrupted before anything could be saved."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.algo not in ALGORITHMS:
        parser.error(f"unknown algorithm {args.algo!r}; choose from {', '.join(ALGORITHMS)}")
    try:
        env_id = check_env_id(args.env_id)
    except ValueError as exc:
        parser.error(str(exc))
    try:
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
            hyperparams=args.hyperparams,
            overwrite=args.overwrite,
            allow_missing_buffer=args.allow_missing_buffer,
        )
    except UserError as exc:
        print(f"{parser.prog}: error: {exc}", file=sys.stderr)
        return 2
    except TrainingInterrupted as stopped:
        given = list(sys.argv[1:] if argv is None else argv)
        again = [a for a in given if a != "--overwrite"] + ["--resume"] * ("--resume" not in given)
        if args.run_dir is None:
            again += ["--run-dir", str(stopped.result.run_dir)]
        print(
            f"Interrupted at {stopped.result.timesteps} steps; saved "
            f"{stopped.result.model_path} and a checkpoint. Continue with: "
            f"{parser.prog} {shlex.join(again)}",
            file=sys.stderr,
        )
        return stopped.exit_code
    except KeyboardInterrupt:
        print("Interrupted; nothing saved since the last checkpoint.", file=sys.stderr)
        return 130
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
