"""Per-environment hyperparameters, RL Zoo style: one YAML file per algorithm, keyed by env id.

Keys the training program interprets itself: `n_timesteps` (default budget), `n_envs`,
`policy`, `normalize` (bool or VecNormalize keyword arguments), `action_noise`
({type: normal, sigma: S}), `policy_kwargs` (with `activation_fn` by name) and schedules
written "lin_X" (linear decay from X to 0). Everything else goes to the algorithm.
"""

from __future__ import annotations

import difflib
from pathlib import Path

import yaml

DIRECTORY = Path(__file__).parent / "hyperparams"
ALGOS = ("ppo", "sac", "td3")


def load(algo: str, env_id: str) -> dict:
    """The hyperparameters of `algo` for `env_id` (a fresh dict)."""
    if algo not in ALGOS:
        close = difflib.get_close_matches(algo, ALGOS, n=1)
        hint = f" Did you mean {close[0]!r}?" if close else ""
        raise ValueError(f"Unknown algorithm {algo!r}.{hint} Known: {', '.join(ALGOS)}.")
    path = DIRECTORY / f"{algo}.yml"
    table = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
    if env_id not in table:
        raise ValueError(
            f"No {algo} hyperparameters for {env_id!r} in {path.name}. "
            f"Environments with {algo} hyperparameters: {', '.join(sorted(table))}."
        )
    return dict(table[env_id])


def check_algo(env_id: str) -> str:
    """The algorithm the main job trains on `env_id` (hyperparams/check.yml; else 'ppo')."""
    table = yaml.safe_load((DIRECTORY / "check.yml").read_text(encoding="utf-8")) or {}
    algo = table.get(env_id, "ppo")
    if algo not in ALGOS:
        raise ValueError(f"check.yml names unknown algorithm {algo!r} for {env_id!r}.")
    return algo
