"""The training budget of a run whose command names none: until solved within
`DEFAULT_SECONDS` (`agents.learning.budget`), and within the steps its task, the packaged
YAML's entry or the user's file declares where one does, so that the plain `python -m
agents.check` ends, for a built-in or a new system alike, at the confirmed verdict or
within ten minutes."""

from __future__ import annotations

from pathlib import Path

from ..common import UserError, task_of
from . import hparams

DEFAULT_SECONDS = 600.0
"""The wall-clock budget of an agent whose command names none (neither --timesteps nor
--budget): it trains until solved, at most 10 minutes (and its declared steps)."""


def seconds_of(timesteps, seconds) -> float | None:
    """The wall-clock budget an agent trains within: `seconds` if given; None where a step
    count is asked for (--timesteps: the steps, to the end); else `DEFAULT_SECONDS`."""
    if seconds or timesteps is not None:
        return seconds or None
    return DEFAULT_SECONDS


def steps_cap(env_id, algo, timesteps, seconds, hyperparams) -> int | None:
    """The steps that cap a run of the default time budget: the n_timesteps declared for
    `env_id` (the task's hyperparameters, the YAML's entry for the env, a --hyperparams
    file), or None where none is declared or the command names a budget of its own."""
    if seconds or timesteps is not None:
        return None
    name = algo or hparams.check_algo(env_id)
    if not declares_steps(name, env_id, hyperparams):
        return None
    return int(hparams.load(name, env_id, hyperparams)["n_timesteps"])


def declares_steps(algo: str, env_id: str, path: str | Path | None = None) -> bool:
    """Whether anything but the YAML's `default` gives `env_id` its n_timesteps for `algo`:
    the task's `hyperparams[algo]`, the packaged YAML's entry for env_id, or the file at
    `path` (its `default` or env_id entry)."""
    tables = [hparams.read_table(hparams.DIRECTORY / f"{algo}.yml").get(env_id, {})]
    try:
        tables.append(task_of(env_id).hyperparams.get(algo, {}))
    except UserError:  # not a Lagrange env: only the files can say
        pass
    if path is not None:
        user = hparams.read_table(Path(path))
        tables += [user.get("default", {}), user.get(env_id, {})]
    return any("n_timesteps" in t for t in tables)
