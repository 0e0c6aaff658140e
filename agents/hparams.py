"""Training hyperparameters: the algorithm's defaults, then what the env's task declares,
then the packaged YAML's entry for the env id (if any), then a user's file.

One YAML file per algorithm (agents/hyperparams/<algo>.yml), RL Zoo style: a `default`
entry for every env, and entries keyed by env id that override it (also for envs that are
not Lagrange envs, such as Pendulum-v1). Keys the training program interprets itself:
`n_timesteps` (default budget), `n_envs`, `policy`, `normalize` (bool or VecNormalize
keyword arguments), `action_noise` ({type: normal, sigma: S}), `policy_kwargs` (with
`activation_fn` by name) and schedules written "lin_X" (linear decay from X to 0).
Everything else goes to the algorithm.
"""

from __future__ import annotations

import difflib
from pathlib import Path

import yaml

from .common import UserError, task_of

DIRECTORY = Path(__file__).parent / "hyperparams"
ALGOS = ("ppo", "sac", "td3")


def _table(path: Path) -> dict:
    try:
        table = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
    except OSError as exc:
        raise UserError(f"Cannot read hyperparameters {path}: {exc.strerror}.") from None
    except yaml.YAMLError as exc:
        raise UserError(f"{path} is not valid YAML: {exc}.") from None
    if not isinstance(table, dict) or not all(isinstance(v, dict) for v in table.values()):
        raise UserError(f"{path} must map env ids (or 'default') to dicts of hyperparameters.")
    return table


def check_algo_name(algo: str) -> str:
    if algo not in ALGOS:
        close = difflib.get_close_matches(str(algo), ALGOS, n=1)
        hint = f" Did you mean {close[0]!r}?" if close else ""
        raise UserError(f"Unknown algorithm {algo!r}.{hint} Known: {', '.join(ALGOS)}.")
    return algo


def load(algo: str, env_id: str, path: str | Path | None = None) -> dict:
    """The hyperparameters of `algo` for `env_id` (a fresh dict): the YAML's `default`,
    updated by the task's `hyperparams[algo]`, the YAML's entry for env_id and, if `path`
    is given, that file's `default` and env_id entries."""
    check_algo_name(algo)
    packaged = _table(DIRECTORY / f"{algo}.yml")
    hp = dict(packaged.get("default", {}))
    try:
        hp.update(task_of(env_id).hyperparams.get(algo, {}))
    except UserError:
        if env_id not in packaged and path is None:
            raise UserError(
                f"No {algo} hyperparameters for {env_id!r}: it is not a Lagrange env and "
                f"{algo}.yml has no entry for it; give --hyperparams FILE."
            ) from None
    hp.update(packaged.get(env_id, {}))
    if path is not None:
        user = _table(Path(path))
        hp.update(user.get("default", {}))
        hp.update(user.get(env_id, {}))
    return hp


def check_algo(env_id: str) -> str:
    """The algorithm the main job trains on `env_id`: the task's `algo` ('ppo' otherwise)."""
    try:
        return check_algo_name(task_of(env_id).algo)
    except UserError:
        return "ppo"
