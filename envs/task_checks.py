"""What a task declaration gets wrong on its own, checked at `Task(...)`, each error naming the
field and the entry (`check_task`; what needs the compiled model is `envs.checks`)."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from dynamics.checks import ALGORITHMS, INTEGRATORS, did_you_mean
from dynamics.spec import ModelSpec

from .checks import DeclarationError
from .checks import declaration_error as _fail

PLANNER = "plan"
"""`hyperparams["plan"]`: the trajectory planner's options (agents.plan)."""


def _is_number(v) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)


def _number(task_name: str, field: str, v, *, finite=True, positive=False) -> None:
    """A declared Number (a number, a parameter name or a function of p): checked if a number."""
    if isinstance(v, str) or (callable(v) and not _is_number(v)):
        return
    if not _is_number(v):
        raise _fail(
            task_name, field, f"must be a number, a parameter name or a function of p; got {v!r}."
        )
    if finite and not math.isfinite(v):
        raise _fail(task_name, field, f"must be finite, got {v!r}.")
    if positive and not v > 0:
        raise _fail(task_name, field, f"must be positive, got {v!r}.")


def _range(task_name: str, field: str, pair) -> None:
    if isinstance(pair, (str, bytes)) or not hasattr(pair, "__len__") or len(pair) != 2:
        raise _fail(task_name, field, f"must be a (low, high) pair, got {pair!r}.")
    lo, hi = pair
    _number(task_name, field, lo)
    _number(task_name, field, hi)
    if _is_number(lo) and _is_number(hi) and lo > hi:
        raise _fail(task_name, field, f"has low {lo!r} above high {hi!r}.")


# ---- at Task(...) --------------------------------------------------------------------------
def check_task(task, features, Goal, Term, LQRHints, Heuristic) -> None:
    """What a task declaration gets wrong on its own (see the module docstring); the
    declaration classes are handed in by `envs.task`, which this module does not import."""
    name = task.name
    if not isinstance(name, str) or not name:
        raise DeclarationError(f"A task's `name` must be a non-empty string, got {name!r}.")
    if isinstance(task.model, ModelSpec):
        raise _fail(
            name,
            "model",
            f"is the ModelSpec {task.model.name!r} itself; give the function that returns it "
            "(model=my_spec, not my_spec()) or dynamics.Model(spec), so it is derived once.",
        )
    _check_actuated(task)
    _check_max_input(task)
    _check_observation(task, features)
    _check_terms(task, Term)
    for field in ("success", "failure", "constants", "draw"):
        v = getattr(task, field)
        if (v is not None or field == "success") and not callable(v):
            raise _fail(name, field, f"must be a function, got {v!r}.")
    _check_goal_start_limits(task, Goal)
    _positive(name, "control_period", task.control_period, float)
    _positive(name, "substeps", task.substeps, int)
    _positive(name, "max_episode_steps", task.max_episode_steps, int)
    _check_learning(task)
    if not isinstance(task.lqr, LQRHints):
        raise _fail(name, "lqr", f"must be an LQRHints, got {task.lqr!r}.")
    _check_hints(name, task.lqr)
    n_a = len(task.actuated)
    if np.ndim(task.lqr.R) > 1 or np.size(task.lqr.R) not in (1, n_a):
        raise _fail(
            name,
            "lqr.R",
            f"must be one weight or one per action component ({n_a}: "
            f"{', '.join(task.actuated)}), got {task.lqr.R!r}.",
        )
    if task.heuristic is not None:
        h = task.heuristic
        if not isinstance(h, Heuristic) or ":" not in str(h.target):
            raise _fail(
                name, "heuristic", f"must be Heuristic(description, 'module:Class'), got {h!r}."
            )
    if not isinstance(task.outputs, (tuple, list)) or not all(
        isinstance(o, str) for o in task.outputs
    ):
        raise _fail(name, "outputs", f"must be a tuple of output names, got {task.outputs!r}.")


def _check_actuated(task) -> None:
    name, actuated = task.name, task.actuated
    if isinstance(actuated, str) or not isinstance(actuated, (tuple, list)) or not actuated:
        raise _fail(
            name, "actuated", f"must name at least one input (a tuple of names), got {actuated!r}."
        )
    repeated = sorted({a for a in actuated if list(actuated).count(a) > 1})
    if repeated:
        raise _fail(
            name, "actuated", f"names {repeated} more than once: each action drives one input."
        )


def _check_observation(task, features) -> None:
    name, Derived = task.name, features[-1]
    if not isinstance(task.observation, (tuple, list)) or not task.observation:
        raise _fail(name, "observation", "must be a non-empty tuple of features.")
    for i, f in enumerate(task.observation):
        if not isinstance(f, features):
            raise _fail(
                name,
                f"observation[{i}]",
                f"is not a feature (Angle, AngleError, Value, Derived): {f!r}.",
            )
        if isinstance(f, Derived):
            if not callable(f.fn):
                raise _fail(name, f"observation[{i}] ({f.name})", "needs a function `fn`.")
            _range(name, f"observation[{i}] ({f.name})", (f.low, f.high))
        if getattr(f, "bound", None) is not None:
            _number(name, f"observation[{i}] ({f.name}).bound", f.bound, positive=True)


def _check_terms(task, Term) -> None:
    name = task.name
    if not task.terms or not all(isinstance(t, Term) for t in task.terms):
        raise _fail(name, "terms", f"must be a non-empty tuple of Term, got {task.terms!r}.")
    names = [t.name for t in task.terms]
    if len(set(names)) != len(names):
        raise _fail(name, "terms", f"must be named once each: {names}.")
    with_fn = [t.fn is not None for t in task.terms]
    if task.reward is None and not all(with_fn):
        missing = [t.name for t in task.terms if t.fn is None]
        raise _fail(
            name,
            "terms",
            f"{missing} need a function (`Term(..., fn=...)`) or the task a `reward`.",
        )
    if task.reward is not None and any(with_fn):
        raise _fail(
            name, "reward", "and `Term(fn=...)` are two ways of giving the reward; give one."
        )
    if task.reward is not None and not callable(task.reward):
        raise _fail(name, "reward", f"must be a function, got {task.reward!r}.")
    for t in task.terms:
        _range(name, f"terms ({t.name})", (t.low, t.high))
        if t.fn is not None and not callable(t.fn):
            raise _fail(name, f"terms ({t.name}).fn", f"must be a function, got {t.fn!r}.")


def _check_goal_start_limits(task, Goal) -> None:
    name = task.name
    if not isinstance(task.goal, (tuple, list)) or not all(isinstance(g, Goal) for g in task.goal):
        raise _fail(
            name,
            "goal",
            f"must be a tuple of Goal(name, unit, low, high), got {task.goal!r:.80} (a goal "
            "is declared with its range, not named: envs.Goal('x*', 'm', -1.0, 1.0)).",
        )
    goals = [g.name for g in task.goal]
    if len(set(goals)) != len(goals):
        raise _fail(name, "goal", f"repeats a component: {goals}.")
    for g in task.goal:
        _range(name, f"goal ({g.name})", (g.low, g.high))
    if isinstance(task.start, Mapping):
        for k, pair in task.start.items():
            _range(name, f"start[{k!r}]", pair)
    elif not callable(task.start):
        raise _fail(
            name,
            "start",
            "must be {state: (low, high)} or a function (rng, p) -> ({state: value}, "
            f"{{goal: value}}); got {task.start!r}.",
        )
    if not isinstance(task.limits, Mapping):
        raise _fail(name, "limits", f"must be {{state: bound}}, got {task.limits!r}.")
    for k, v in task.limits.items():
        _number(name, f"limits[{k!r}]", v, positive=True)
    op = task.operating_point
    if op is not None and not (isinstance(op, Mapping) or callable(op)):
        raise _fail(name, "operating_point", f"must be a dict or a function, got {op!r}.")
    for k, v in dict(op).items() if isinstance(op, Mapping) else ():
        _number(name, f"operating_point[{k!r}]", v)


def _check_learning(task) -> None:
    """The integrator, the learner and its settings: names from the one tables of
    `dynamics.checks` (an algorithm agents cannot train is refused, never trained as another)."""
    name = task.name
    if task.integrator not in INTEGRATORS:
        raise _fail(
            name,
            "integrator",
            f"must be one of {INTEGRATORS}, got "
            f"{task.integrator!r}.{did_you_mean(task.integrator, INTEGRATORS)}",
        )
    if task.algo not in ALGORITHMS:
        raise _fail(
            name,
            "algo",
            f"must be one of {ALGORITHMS} (the algorithms agents.train trains), got "
            f"{task.algo!r}.{did_you_mean(task.algo, ALGORITHMS)}",
        )
    if not isinstance(task.hyperparams, Mapping):
        raise _fail(
            name, "hyperparams", f"must map an algorithm to its settings, got {task.hyperparams!r}."
        )
    for algo, settings in task.hyperparams.items():
        if algo not in (*ALGORITHMS, PLANNER):
            raise _fail(
                name,
                "hyperparams",
                f"names unknown algorithm {algo!r}; known: {ALGORITHMS} and {PLANNER!r}."
                f"{did_you_mean(algo, (*ALGORITHMS, PLANNER))}",
            )
        if not isinstance(settings, Mapping):
            raise _fail(name, f"hyperparams[{algo!r}]", f"must be a mapping, got {settings!r}.")


def _positive(task_name: str, field: str, value, kind) -> None:
    ok = isinstance(value, (int, np.integer)) if kind is int else _is_number(value)
    if isinstance(value, bool) or not ok:
        raise _fail(
            task_name,
            field,
            f"must be {'an integer' if kind is int else 'a number'}, got {value!r}.",
        )
    if not (math.isfinite(value) and value > 0):
        raise _fail(task_name, field, f"must be positive and finite, got {value!r}.")


def _check_max_input(task) -> None:
    name, value, n = task.name, task.max_input, len(task.actuated)
    if callable(value) and not _is_number(value):
        return
    items = [value] * n if _is_number(value) or isinstance(value, str) else value
    if not isinstance(items, (tuple, list)) or len(items) != n:
        raise _fail(
            name,
            "max_input",
            f"needs one limit per actuated input {tuple(task.actuated)}, got {value!r}.",
        )
    for inp, v in zip(task.actuated, items):
        if isinstance(v, (tuple, list)):  # an asymmetric (low, high) limit
            _range(name, f"max_input[{inp!r}]", v)
            lo, hi = v
            if _is_number(lo) and _is_number(hi) and not lo < hi:
                raise _fail(name, f"max_input[{inp!r}]", f"needs low < high, got {v!r}.")
        else:
            _number(name, f"max_input[{inp!r}]", v, positive=True)


def _check_hints(task_name: str, hints) -> None:
    for k, v in dict(hints.scales).items():
        _number(task_name, f"lqr.scales[{k!r}]", v, positive=True)
    _number(task_name, "lqr.default_scale", hints.default_scale, positive=True)
    for r in np.ravel(hints.R):
        _number(task_name, "lqr.R", r, positive=True)
    for k, v in dict(hints.region or {}).items():
        _number(task_name, f"lqr.region[{k!r}]", v)
        if _is_number(v) and v < 0:
            raise _fail(task_name, f"lqr.region[{k!r}]", f"must not be negative, got {v!r}.")
