"""Small helpers shared by the training, evaluation and checking programs.

Environment-id checking (with close matches and Gymnasium's module:Env-v0 form), the
Lagrange env behind a wrapper, atomic file writes, torch thread settings and argparse types
that reject bad budgets with a clear message.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import math
import os
from pathlib import Path
from typing import NoReturn

import gymnasium as gym

from dynamics.checks import did_you_mean
from dynamics.files import (
    atomic_path,  # noqa: F401  (re-exported: one atomic writer)
    write_atomic,  # noqa: F401
)

DEFAULT_TORCH_THREADS = 1  # measured: see benchmarks/baselines.py --threads (2 threads is slower)


class UserError(ValueError):
    """A mistake in what the user asked for: command-line programs print its message as
    one line, without a traceback."""


def register_envs() -> tuple[str, ...]:
    """Import `envs` (which registers the built-in Lagrange environments); their ids."""
    import envs

    return envs.ENV_IDS


def check_env_id(env_id: str, lagrange: bool = False) -> str:
    """The registered id named by `env_id` ('NS/Name-vN', or Gymnasium's 'module:NS/Name-vN',
    which imports the module that registers it first); UserError naming close matches
    otherwise. With `lagrange`, the env must also be built on the Lagrange runtime."""
    if not isinstance(env_id, str):
        raise TypeError(f"Environment id must be a string, got {type(env_id).__name__}.")
    register_envs()
    module, sep, name = env_id.partition(":")
    if sep:
        try:
            importlib.import_module(module)
        except ModuleNotFoundError as exc:
            raise UserError(
                f"Cannot import module {module!r} of {env_id!r} (it should register the env "
                f"when imported): {exc}."
            ) from None
        env_id = name
    if env_id not in gym.registry:
        known = sorted(gym.registry)
        hint = did_you_mean(env_id, known, n=3)
        if not hint:  # 'TwoLinkArm' should still find 'Lagrange/TwoLinkArm-v1'
            hint = did_you_mean(env_id, [k for k in known if env_id.lower() in k.lower()], 3)
        raise UserError(
            f"Unknown environment id {env_id!r}.{hint} Lagrange environments: "
            f"{', '.join(register_envs())}; a system of your own: 'your.module:NS/Name-v0'."
        )
    if lagrange:
        task_of(env_id)
    return env_id


def check_env_ids(env_ids, lagrange: bool = False) -> list[str]:
    """`check_env_id` of each of `env_ids`; UserError where one is named twice (it would be
    trained and reported twice)."""
    checked = [check_env_id(e, lagrange) for e in env_ids]
    twice = sorted({e for e in checked if checked.count(e) > 1})
    if twice:
        raise UserError(f"{', '.join(twice)} given twice; name each env once.")
    return checked


def check_file_applies(table: dict, path, env_id: str) -> None:
    """UserError when the hyperparameter file at `path` (its `table`) has no entry for
    `env_id` nor a `default` and names an env that is not registered: a misspelt id would
    otherwise be ignored without a word."""
    stray = [k for k in table if k != "default" and k not in gym.registry]
    if stray and env_id not in table and "default" not in table:
        raise UserError(
            f"{path}: no entry for {env_id} nor a 'default', and "
            f"{', '.join(map(repr, stray))} names no registered env."
            f"{did_you_mean(stray[0], [env_id, 'default', *gym.registry])}"
        )


def plain_warnings() -> None:
    """Print warnings as one-line messages ("warning: ..." on stderr) instead of Python's
    form with the library's file, line and source: for the command-line entry points, whose
    users read messages, not tracebacks."""
    import sys
    import warnings

    def show(message, category, filename, lineno, file=None, line=None) -> None:
        try:
            print(f"warning: {message}", file=file or sys.stderr)
        except OSError:  # stderr closed: nothing to say it on
            pass

    warnings.showwarning = show


def fail(parser, message) -> NoReturn:
    """End a command-line program on a user error: one line, exit status 2."""
    parser.exit(2, f"{parser.prog}: error: {message}\n")


def task_of(env_id: str):
    """The `envs.Task` of a registered Lagrange env id; UserError for other envs."""
    import envs

    spec = gym.spec(env_id)
    task = spec.kwargs.get("task")
    if not isinstance(task, envs.Task):
        raise UserError(
            f"{env_id!r} is not built on the Lagrange runtime, so agents know nothing of its "
            "physics (operating point, LQR weights, heuristic). Register a system of your "
            "own as an envs.Task (see docs/new-system.md)."
        )
    return task


def lagrange_env(env):
    """The unwrapped Lagrange env (single or vector) of `env`; UserError for other envs."""
    import envs

    base = env.unwrapped if hasattr(env, "unwrapped") else env
    if not isinstance(base, (envs.LagrangianEnv, envs.LagrangianVectorEnv)):
        raise UserError(
            f"{base!r} is not built on the Lagrange runtime (envs.LagrangianEnv or "
            "envs.LagrangianVectorEnv), so agents know nothing of its physics. Register a "
            "system of your own as an envs.Task (see docs/new-system.md)."
        )
    return base


def lagrange_of(venv):
    """The Lagrange env under SB3 vector wrappers (a native vector env, or the first env
    of a DummyVecEnv / SubprocVecEnv-like)."""
    inner = venv
    while True:
        if hasattr(inner, "envs"):
            return lagrange_env(inner.envs[0])
        nxt = getattr(inner, "venv", None)
        if nxt is None:
            return lagrange_env(inner)
        inner = nxt


def set_torch_threads(n: int = DEFAULT_TORCH_THREADS) -> None:
    """Limit torch's intra-op threads (small MLPs on a shared box are faster on one)."""
    import torch

    if n < 1:
        raise ValueError(f"Number of torch threads must be at least 1, got {n}.")
    torch.set_num_threads(n)


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1, with a message that says what was given."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {value}")
    return value


def positive_number(text: str) -> float:
    """argparse type: a positive finite number."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {value}")
    return value


def non_negative_int(text: str) -> int:
    """argparse type: an integer >= 0."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {value}")
    return value


SEED_LIMIT = 2**32
"""Seeds are below this: stable-baselines3 seeds numpy's global generator, which takes no
larger seed; every command's --seed keeps to it, so one seed means the same in each."""


def seed_int(text: str) -> int:
    """argparse type: a seed, an integer from 0 to SEED_LIMIT - 1."""
    value = non_negative_int(text)
    if value >= SEED_LIMIT:
        raise argparse.ArgumentTypeError(
            f"expected a seed from 0 to 2**32 - 1 (numpy's limit), got {value:.3g}"
        )
    return value


def writable_folder(path, option: str) -> None:
    """UserError unless `path` is (or can be made) a folder this process can write into
    (checked before the work, which would otherwise be lost)."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise UserError(f"{option} {path} is a file, not a folder.")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"{option} {path} cannot be made: {exc.strerror or exc}.") from None
    if not os.access(path, os.W_OK | os.X_OK):
        raise UserError(f"{option} {path} is not writable by this user.")


def env_slug(env_id: str) -> str:
    """A file-system name for an environment id ('Lagrange/Acrobot-v2' -> 'Lagrange-Acrobot-v2')."""
    return env_id.replace("/", "-").replace(":", "-")


def trained_line(algo: str, env_id: str, result) -> str:
    """agents.train's last line: steps, time, the last evaluation, when solved, the model."""
    rate = "" if result.success_rate is None else f", success {result.success_rate:.0%}"
    evaluation = (
        "no evaluation"
        if result.eval_mean is None
        else f"last evaluation {result.eval_mean:.1f} (sd {result.eval_std:.1f}){rate}"
    )
    solved, when = result.solved, ""
    if solved:
        when = f" Solved after {solved['seconds']:.0f} s, {solved['timesteps']} steps."
    return (
        f"{algo} on {env_id}: {result.timesteps} steps in {result.wall_s:.0f} s, "
        f"{evaluation}.{when} Model: {result.model_path}"
    )


_APPLIED: dict[str, dict[str, float]] = {}  # env id -> the values `applied` set


@contextlib.contextmanager
def applied(env_id: str, values: dict[str, float] | None):
    """Within the block, `spec(env_id)` (what the agents make their envs from) carries
    `values`; Gymnasium's registry is never written. None: nothing to do."""
    if not values:
        yield
        return
    _APPLIED[env_id] = dict(values)
    try:
        yield
    finally:
        _APPLIED.pop(env_id, None)


def spec(env_id: str):
    """What the agents pass to `gym.make` / `gym.make_vec` for `env_id`: the id itself, or
    within `applied` a copy of its registration with the values among its keyword
    arguments (`gym.make(id, **values)` would give the same env)."""
    values = _APPLIED.get(env_id)
    if not values:
        return env_id
    import dataclasses

    registered = gym.spec(env_id)
    return dataclasses.replace(registered, kwargs={**registered.kwargs, **values})


def current(env_id: str) -> dict[str, float]:
    """The values `applied` has set for `env_id` ({} outside it)."""
    return dict(_APPLIED.get(env_id, {}))
