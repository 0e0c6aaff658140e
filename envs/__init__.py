"""Gymnasium environments of Lagrangian systems: a task declaration on one batched runtime.

Importing this package registers the built-in tasks in the `Lagrange` namespace, each with
its episode limit and a native `vector_entry_point` (`ENV_IDS`: the current version of
each; `Lagrange/Acrobot-v1`, the 3 N*m acrobot, stays registered)::

    import gymnasium as gym
    import envs

    env = gym.make("Lagrange/TwoLinkArm-v1")
    vec = gym.make_vec("Lagrange/TwoLinkArm-v1", num_envs=1024,
                       vectorization_mode="vector_entry_point")

A new system is a `Task` (see `envs.task`) on any model, registered with one call of
`gymnasium.register` (`register` below is that call, spelled out).
"""

import importlib.abc
import sys
import warnings

from gymnasium.envs.registration import registry

from dynamics import wrap

from . import docs  # noqa: F401  (envs.docs.describe)
from .env import LagrangianEnv
from .randomize import Choice, LogUniform, Same, TruncNormal, Uniform
from .task import Angle, AngleError, Derived, Goal, Heuristic, LQRHints, Task, Term, Value
from .tasks.swing_up import swing_up_ppo  # noqa: F401  (envs.swing_up_ppo)
from .vector import LagrangianVectorEnv


def register(env_id: str, task: Task, **kwargs) -> None:
    """`gymnasium.register(env_id, ...)` for a task: the single and vector entry points,
    the task, and its `max_episode_steps` (override with max_episode_steps=...).
    Registering an id again with the same task does nothing; with another task it warns
    and replaces it (as Gymnasium does): give a changed task a new version instead."""
    import gymnasium

    if env_id in registry:
        old = registry[env_id].kwargs.get("task")
        if old is task or old == task:
            return
        warnings.warn(
            f"{env_id} is registered already with another task ({getattr(old, 'name', old)!r}"
            f"); replacing it. If the task's rewards, termination or dynamics changed, "
            "register it under a new version instead.",
            UserWarning,
            stacklevel=2,
        )
    gymnasium.register(
        id=env_id,
        entry_point="envs:LagrangianEnv",
        vector_entry_point="envs:LagrangianVectorEnv",
        kwargs={"task": task, **kwargs.pop("kwargs", {})},
        max_episode_steps=kwargs.pop("max_episode_steps", task.max_episode_steps),
        **kwargs,
    )


def _register_builtins() -> tuple[str, ...]:
    """Register every built-in version (`envs.tasks`); return the current one of each."""
    from .tasks import CURRENT, OLDER

    for env_id, task in {**CURRENT, **OLDER}.items():
        register(env_id, task)
    return tuple(CURRENT)


ENV_IDS: tuple[str, ...] = _register_builtins()

_MOVED = ("arm", "acrobot", "disk", "bead", "crank", "bicycle", "swing_up", "rendering_bicycle")


def _moved(name: str) -> str:
    return f"envs.{name} moved to envs.tasks.{name} (the built-in tasks' own wing): import that"


class _MovedFinder(importlib.abc.MetaPathFinder):
    """`import envs.arm` (the built-in tasks' home before the tasks wing) ends in one line
    that names the new module, not a bare "No module named"."""

    def find_spec(self, fullname, path=None, target=None):
        head, _, tail = fullname.rpartition(".")
        if head == __name__ and tail in _MOVED:
            raise ImportError(_moved(tail), name=fullname)
        return None


if not any(isinstance(f, _MovedFinder) for f in sys.meta_path):
    sys.meta_path.append(_MovedFinder())


def __getattr__(name: str):
    """`envs.arm` (the old home of a built-in task) says where it went."""
    if name in _MOVED:
        raise AttributeError(_moved(name))
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "ENV_IDS",
    "Angle",
    "AngleError",
    "Choice",
    "Derived",
    "Goal",
    "Heuristic",
    "LQRHints",
    "LagrangianEnv",
    "LagrangianVectorEnv",
    "LogUniform",
    "Same",
    "Task",
    "Term",
    "TruncNormal",
    "Uniform",
    "Value",
    "register",
    "wrap",
]
