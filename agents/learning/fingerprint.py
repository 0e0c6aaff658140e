"""Which declaration of a task a run was trained on: a fingerprint recorded in the run's
config.yml, so that a run is never reused for a task that has changed since."""

from __future__ import annotations

from pathlib import Path

from ..common import UserError
from ..common import spec as current_spec


def task_fingerprint(env_id: str) -> str | None:
    """A hash of what the env's registration declares (the task's fields, with the source
    of its functions and of a model factory, and the registry's other options), or None
    for an env that is not a Lagrange env. A run records it in config.yml; `agents.check`
    refuses to resume or reuse a run recorded with another (the likeliest source of the
    README's former Furuta "PPO 90 %", which the commit that wrote it does not give on a
    fresh clone: a run on disk whose hyperparameters matched, reused)."""
    import dataclasses
    import hashlib
    import inspect

    import gymnasium as gym

    spec = current_spec(env_id)  # with the values of --params, where applied
    spec = gym.spec(spec) if isinstance(spec, str) else spec
    task = spec.kwargs.get("task")
    if task is None or not dataclasses.is_dataclass(task):
        return None

    def text(v) -> str:
        if dataclasses.is_dataclass(v) and not isinstance(v, type):
            inner = ",".join(f"{f.name}={text(getattr(v, f.name))}" for f in dataclasses.fields(v))
            return f"{type(v).__name__}({inner})"
        if isinstance(v, dict) or hasattr(v, "items"):
            return "{" + ",".join(f"{k!r}:{text(x)}" for k, x in sorted(v.items(), key=str)) + "}"
        if isinstance(v, (list, tuple)):
            return "(" + ",".join(text(x) for x in v) + ")"
        if callable(v):
            try:
                return inspect.getsource(v)
            except (OSError, TypeError):
                return getattr(v, "__qualname__", repr(type(v)))
        return repr(v)

    others = {k: v for k, v in spec.kwargs.items() if k != "task"}
    blob = f"{text(task)}|{text(others)}|{spec.max_episode_steps}"
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def check_fingerprint(run_dir: Path, env_id: str) -> None:
    """UserError when `run_dir` holds a run trained on another declaration of the task."""
    from .rundir import read_config

    if not (Path(run_dir) / "config.yml").exists():
        return
    then, now = read_config(Path(run_dir)).get("task"), task_fingerprint(env_id)
    if now is not None and then != now:
        raise UserError(
            f"{run_dir} holds a run trained on another declaration of {env_id} (task "
            f"fingerprint {then or 'none recorded'} in the run, {now} now: the task's "
            "declaration changed since, or the run predates fingerprints); pass --fresh to "
            "retrain it, or --out DIR to keep it."
        )
