"""The training budget of a run whose command names none: the steps its task, the packaged
YAML's entry or the user's file declares, or else until solved within `DEFAULT_SECONDS`
(`agents.learning.budget`), so that a new system trains to a policy with the plain
`python -m agents.check MODULE:ID`."""

from __future__ import annotations

from pathlib import Path

from ..common import UserError, task_of
from . import hparams

DEFAULT_SECONDS = 600.0
"""The wall-clock budget of a system that declares no training budget of its own: with
neither --timesteps nor --budget, its agent trains until solved, at most 10 minutes."""


def seconds_of(env_id, algo, timesteps, seconds, hyperparams) -> float | None:
    """The wall-clock budget `env_id`'s agent trains within: `seconds` if given; else
    `DEFAULT_SECONDS` where no step count is asked for or declared (the task's
    hyperparameters, the YAML's entry for the env, a --hyperparams file); else None (the
    declared steps)."""
    if seconds or timesteps is not None:
        return seconds or None
    name = algo or hparams.check_algo(env_id)
    return None if declares_steps(name, env_id, hyperparams) else DEFAULT_SECONDS


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
