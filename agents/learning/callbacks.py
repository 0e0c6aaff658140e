"""The training run's callbacks (SB3's, adapted) and checkpoints: checkpoints written
atomically on the run's own timestep schedule and read back (`build_or_load`), evaluations
on the same schedule across resumes, and a graceful stop on SIGINT/SIGTERM that every long
phase (learning, evaluation) polls."""

from __future__ import annotations

import copy
import signal
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import (
    BaseCallback,
    CallbackList,
    CheckpointCallback,
    EvalCallback,
    ProgressBarCallback,
)
from stable_baselines3.common.logger import Logger, make_output_format
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.save_util import save_to_pkl
from stable_baselines3.common.vec_env import VecEnv, VecNormalize

from ..common import UserError, atomic_path
from .curves import CurveLogger
from .hparams import algo_kwargs, algorithms
from .rundir import CHECKPOINT_PREFIX, companion


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


class ScheduledEval(EvalCallback):
    """SB3's EvalCallback, run at the first step after the run's timestep count passes each
    multiple of `every`. SB3 counts its own calls, which restart at zero when a run is
    resumed; counting the model's timesteps puts a resumed run's evaluations on the same
    steps as an uninterrupted run's. With `stop`, an evaluation in progress ends at the
    next step after a signal (`EvaluationStopped`): its episodes can take minutes (the
    hand-over simulates LQR at each step) and SB3 looks at callbacks only between them."""

    def __init__(self, eval_env: VecEnv, every: int, stop: GracefulStop | None = None, **kw):
        super().__init__(eval_env, eval_freq=1, **kw)  # every call that reaches it
        self.every = every
        self.stop = stop
        self._seen = 0

    def _log_success_callback(self, locals_: dict, globals_: dict) -> None:
        if self.stop is not None and self.stop.signum is not None:
            raise EvaluationStopped
        super()._log_success_callback(locals_, globals_)

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

    def due(self) -> bool:
        """Whether the run's timestep count passed a multiple of `every` since the last call."""
        before, self._seen = self._seen, self.num_timesteps
        return _crossed(before, self.num_timesteps, self.every)

    def _on_step(self) -> bool:
        return super()._on_step() if self.due() else True


class LogProgress(BaseCallback):
    """Progress as one line every `every` seconds (and at the end), for output that is not
    a terminal, where a progress bar shows nothing until the run ends. `time_left` (a
    budget run's clock): seconds left; the run ends at whichever comes first, the steps or
    the time, and the line counts towards that one."""

    every = 30.0

    def __init__(self, label: str, stream=None, time_left: Callable[[], float] | None = None):
        super().__init__()
        self.label, self.stream, self.time_left = label, stream, time_left
        self._start = self._next = 0.0
        self._first = self._total = 0

    def _on_training_start(self) -> None:
        self._start = time.monotonic()
        self._next = self._start + self.every
        self._first = self.num_timesteps
        self._total = int(self.locals["total_timesteps"])

    def _on_step(self) -> bool:
        if time.monotonic() >= self._next:
            self._line()
            self._next = time.monotonic() + self.every
        return True

    def _on_training_end(self) -> None:
        self._line()

    def _line(self) -> None:
        now, done = time.monotonic(), self.num_timesteps
        rate = (done - self._first) / max(now - self._start, 1e-9)
        left = max(self._total - done, 0) / rate if rate > 0 else float("inf")
        clock_left = max(self.time_left(), 0.0) if self.time_left is not None else float("inf")
        if clock_left < left:  # the budget's time ends the run first
            done_text, left = f"{done:,} steps", clock_left
        else:
            done_text = f"{done:,}/{self._total:,} steps ({done / self._total:.0%})"
        print(
            f"  {self.label}: {done_text}, {rate:,.0f} steps/s, about {left / 60:.1f} min left",
            file=self.stream or sys.stderr,
            flush=True,
        )


class BudgetBar(ProgressBarCallback):
    """SB3's progress bar over a budget run's seconds, with the steps trained beside it (the
    run's step count is only a cap, which the time or success ends first)."""

    def __init__(self, time_left: Callable[[], float]):
        super().__init__()
        self.time_left = time_left
        self._seconds = 0.0

    def _on_training_start(self) -> None:
        from tqdm.rich import tqdm  # as SB3's bar (whose import silenced its warning)

        self._seconds = max(self.time_left(), 0.0)
        self.pbar = tqdm(total=round(self._seconds), unit="s")

    def _on_step(self) -> bool:
        spent = min(round(self._seconds - self.time_left()), self.pbar.total)
        if spent > self.pbar.n:  # tqdm redraws at most every 0.1 s of its own
            self.pbar.set_description(f"{self.num_timesteps:,} steps", refresh=False)
            self.pbar.update(spent - self.pbar.n)
        return True


class EvaluationStopped(Exception):
    """A signal ended an evaluation during training (the run is saved as after any stop)."""


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


def learn(
    model: BaseAlgorithm,
    total: int,
    callbacks: list,
    fresh: bool,
    progress: str,
    time_left: Callable[[], float] | None = None,
):
    """model.learn up to `total` steps with `callbacks` (stopping at the first that asks),
    showing progress under the label `progress` (and, for a budget run, the `time_left`)."""
    # our own progress bar, so that it is closed (and its refresh thread stopped) however
    # learn() ends; SB3's (progress_bar=True) is closed only when training ends normally.
    # Where stderr is not a terminal (a log file), a line every LogProgress.every seconds
    # (`progress` is the lines' label; empty: no progress shown).
    bar = None
    if progress:
        if not sys.stderr.isatty():
            bar = LogProgress(progress, time_left=time_left)
        else:
            bar = ProgressBarCallback() if time_left is None else BudgetBar(time_left)
    model.set_logger(quiet_logger(model.verbose))
    try:
        model.learn(
            total - model.num_timesteps,
            callback=_StopFirst(callbacks + ([bar] if bar else [])),
            reset_num_timesteps=fresh,
        )
    except EvaluationStopped:  # a signal during an evaluation: saved as after any stop
        pass
    finally:
        if bar is not None and hasattr(bar, "pbar"):
            bar.pbar.close()


def quiet_logger(verbose: int) -> Logger:
    """SB3's logger as `learn` configures it by default (the table on stdout with `verbose`,
    else nothing), without the empty directory its default makes in the temp directory at
    every `learn` (the run directory holds what a run writes)."""
    formats = [make_output_format("stdout", "")] if verbose else []
    return Logger(folder=None, output_formats=formats)


# ---- the model: new, or read back from a checkpoint; saved -------------------------------
def build_or_load(
    algo, hp, env: VecEnv, seed, found, ckpt_dir: Path, verbose, allow_missing_buffer=False
) -> BaseAlgorithm:
    """A new model for `env`, or (`found`: (steps, path)) the checkpoint's, with its
    normalisation statistics and replay buffer."""
    cls = algorithms()[algo]
    if found is None:
        kwargs = algo_kwargs(algo, hp, int(np.prod(env.action_space.shape)))
        return cls(
            hp.get("policy", "MlpPolicy"), env, seed=seed, device="cpu", verbose=verbose, **kwargs
        )
    steps, path = found
    stats = companion(ckpt_dir, "vecnormalize", steps)
    if isinstance(env, VecNormalize):
        if not stats.exists():
            raise UserError(
                f"Checkpoint {path} has no normalisation statistics ({stats.name}); "
                "it cannot be resumed (--overwrite starts afresh)."
            )
        env = _loaded(stats, lambda: VecNormalize.load(str(stats), env.venv))
    buffer = companion(ckpt_dir, "replay_buffer", steps)
    off_policy = issubclass(cls, OffPolicyAlgorithm)
    if off_policy and not buffer.exists():
        if not allow_missing_buffer:
            raise UserError(
                f"Checkpoint {path} has no replay buffer ({buffer.name}); resuming would "
                "start from an empty one. Pass --allow-missing-buffer to accept that."
            )
        print(f"No replay buffer for {path.name}: resuming with an empty one.", file=sys.stderr)
    model = _loaded(path, lambda: cls.load(path, env=env, device="cpu"))
    if off_policy and buffer.exists():
        load_replay_buffer(model, buffer)
    print(f"Resuming from {path} at {model.num_timesteps} timesteps.", file=sys.stderr)
    return model


def _loaded(path: Path, load):
    """`load()`, a damaged checkpoint file (truncated, foreign) a one-line UserError."""
    try:
        return load()
    except Exception as exc:
        raise UserError(
            f"Checkpoint file {path} cannot be loaded ({type(exc).__name__}: "
            f"{' '.join(str(exc).split())[:80]}); --overwrite starts afresh."
        ) from None


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
