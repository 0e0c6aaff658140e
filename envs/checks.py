"""Every declaration checked where it is made, each error naming the field and the entry.

`check_task` runs at `Task(...)` on what can be checked alone; `check_with_model` runs when
an env is made, on what needs the compiled model (names, ranges inside limits, the operating
point, the mass matrix, the inputs); `trial_run` calls the task's functions once as plain
numpy on sample rows, with read-only inputs, before the runtime compiles them.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Callable, Mapping

import numpy as np

ALGORITHMS = ("ppo", "sac", "td3", "a2c", "ddpg")
"""The stable-baselines3 algorithms a task may name in `algo` and `hyperparams`."""
PLANNER = "plan"
"""`hyperparams["plan"]`: the trajectory planner's options (agents.plan)."""
INTEGRATORS = ("rk4", "dop853")


class Unsupported(ValueError):
    """An agent that would be silently wrong on this plant refuses it (time-dependent
    dynamics for an agent designed at one time, coordinates the observation leaves out)."""


class DeclarationError(ValueError):
    """A task or model declaration that cannot work; the message names field and entry."""


def _fail(task_name: str, field: str, problem: str) -> DeclarationError:
    return DeclarationError(f"Task {task_name!r}: `{field}` {problem}")


def _hint(name: str, known) -> str:
    close = difflib.get_close_matches(str(name), list(known), n=1)
    return f" Did you mean {close[0]!r}?" if close else ""


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


# ---- what users hand in at make, reset and step ---------------------------------------------
def positive_float(name: str, value) -> float:
    if isinstance(value, (bool, str, bytes, complex, np.complexfloating)):
        raise TypeError(f"{name} must be a real number, got {value!r}.")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a number, got {value!r}.") from None
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}.")
    return v


def positive_int(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an integer, got {value!r}.")
    if value < 1:
        raise ValueError(f"{name} must be at least 1, got {value}.")
    return int(value)


def real_array(value, name: str) -> np.ndarray:
    """`value` as float64; TypeError for complex, object or non-numeric input."""
    a = np.asarray(value)
    kind = a.dtype.kind
    if kind == "f":
        return a.astype(np.float64, copy=False)
    if kind == "c":
        raise TypeError(f"{name} must be real, got complex values {value!r}.")
    if kind not in "biu":
        raise TypeError(f"{name} must be numeric, got dtype {a.dtype}.")
    return a.astype(np.float64)


def checked_rows(value, shape: tuple[int, ...], name: str, batch: int | None) -> np.ndarray:
    """`value` as rows of `shape`: one value (shared by every row when `batch` is given) or,
    for a vector env (`batch` rows), exactly `batch` rows; finite."""
    a = real_array(value, name)
    if batch is not None and a.shape == (batch,) + shape:
        rows = a
    elif a.shape == shape:
        rows = a[None] if batch is None else np.broadcast_to(a, (batch,) + shape)
    else:
        expected = (
            f"{shape}" if batch is None else f"{shape} or ({batch}, {', '.join(map(str, shape))})"
        )
        raise ValueError(f"Expected {name} of shape {expected}, got {a.shape}.")
    if not np.isfinite(rows).all():
        raise ValueError(f"{name} contains NaN or inf.")
    return np.array(rows, dtype=np.float64)


# ---- at Task(...) --------------------------------------------------------------------------
def check_task(task, features, Goal, Term, LQRHints, Heuristic) -> None:
    """What a task declaration gets wrong on its own (see the module docstring); the
    declaration classes are handed in by `envs.task`, which this module does not import."""
    Derived = features[-1]
    name = task.name
    if not isinstance(name, str) or not name:
        raise DeclarationError(f"A task's `name` must be a non-empty string, got {name!r}.")
    actuated = task.actuated
    if isinstance(actuated, str) or not isinstance(actuated, (tuple, list)) or not actuated:
        raise _fail(
            name, "actuated", f"must name at least one input (a tuple of names), got {actuated!r}."
        )
    repeated = sorted({a for a in actuated if list(actuated).count(a) > 1})
    if repeated:
        raise _fail(
            name, "actuated", f"names {repeated} more than once: each action drives one input."
        )
    _check_max_input(task)
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
    for field in ("success", "failure", "constants", "draw"):
        v = getattr(task, field)
        if (v is not None or field == "success") and not callable(v):
            raise _fail(name, field, f"must be a function, got {v!r}.")
    goals = [g.name for g in task.goal]
    if not all(isinstance(g, Goal) for g in task.goal):
        raise _fail(name, "goal", f"must be a tuple of Goal, got {task.goal!r}.")
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
            f"must be {{state: (low, high)}} or a function (rng, p) -> (x, g); got {task.start!r}.",
        )
    if not isinstance(task.limits, Mapping):
        raise _fail(name, "limits", f"must be {{state: bound}}, got {task.limits!r}.")
    for k, v in task.limits.items():
        _number(name, f"limits[{k!r}]", v, positive=True)
    op = task.operating_point
    if op is not None and not (isinstance(op, Mapping) or callable(op)):
        raise _fail(name, "operating_point", f"must be a dict or a function, got {op!r}.")
    _positive(name, "control_period", task.control_period, float)
    _positive(name, "substeps", task.substeps, int)
    _positive(name, "max_episode_steps", task.max_episode_steps, int)
    if task.integrator not in INTEGRATORS:
        raise _fail(
            name,
            "integrator",
            f"must be one of {INTEGRATORS}, got "
            f"{task.integrator!r}.{_hint(task.integrator, INTEGRATORS)}",
        )
    if task.algo not in ALGORITHMS:
        raise _fail(
            name,
            "algo",
            f"must be one of {ALGORITHMS}, got {task.algo!r}.{_hint(task.algo, ALGORITHMS)}",
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
                f"names unknown algorithm {algo!r}; known: {ALGORITHMS}.{_hint(algo, ALGORITHMS)}",
            )
        if not isinstance(settings, Mapping):
            raise _fail(name, f"hyperparams[{algo!r}]", f"must be a mapping, got {settings!r}.")
    if not isinstance(task.lqr, LQRHints):
        raise _fail(name, "lqr", f"must be an LQRHints, got {task.lqr!r}.")
    _check_hints(name, task.lqr)
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


# ---- at make, with the model ---------------------------------------------------------------
def _known(task_name: str, field: str, names, known, what: str) -> None:
    for k in names:
        if k not in known:
            raise _fail(
                task_name,
                field,
                f"names unknown {what} {k!r}.{_hint(k, known)} Known: {', '.join(known)}.",
            )


def check_with_model(plant) -> None:
    """What needs the compiled model: names, ranges inside limits, parameters shadowed,
    inputs without a force, the mass matrix at sample starts, the operating point."""
    task, names = plant.task, plant.state_names
    name = task.name
    hints = task.lqr
    _known(name, "lqr.states", hints.states or (), names, "state component")
    _known(name, "lqr.scales", dict(hints.scales), names, "state component")
    _known(name, "lqr.region", dict(hints.region or {}), names, "state component")
    op = task.operating_point
    if isinstance(op, Mapping):
        _known(name, "operating_point", op, names, "state component")
        for k, v in op.items():
            if isinstance(v, str) and v not in plant.goal_names and v not in plant.p.dtype.names:
                known = list(plant.goal_names) + list(plant.p.dtype.names)
                raise _fail(
                    name,
                    f"operating_point[{k!r}]",
                    f"names {v!r}, neither a goal component nor a parameter.{_hint(v, known)}",
                )
    if isinstance(task.start, Mapping):
        for k, (lo, hi) in task.start.items():
            i = names.index(k)
            lo, hi = plant.resolve(lo), plant.resolve(hi)
            if lo > hi:
                raise _fail(name, f"start[{k!r}]", f"has low {lo:.6g} above high {hi:.6g}.")
            if max(abs(lo), abs(hi)) > plant.limits[i]:
                raise _fail(
                    name,
                    f"start[{k!r}]",
                    f"= ({lo:.6g}, {hi:.6g}) reaches beyond `limits[{k!r}]` = "
                    f"{plant.limits[i]:.6g}: every such episode would diverge at once.",
                )
    for j, g in enumerate(task.goal):
        lo, hi = plant.goal_low[j], plant.goal_high[j]
        if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
            raise _fail(
                name,
                f"goal ({g.name})",
                f"range [{lo:.6g}, {hi:.6g}] must be finite with low <= high.",
            )
    if not (np.isfinite(plant.term_low).all() and np.isfinite(plant.term_high).all()):
        bad = [
            t.name
            for t, lo, hi in zip(task.terms, plant.term_low, plant.term_high)
            if not (np.isfinite(lo) and np.isfinite(hi))
        ]
        raise _fail(
            name,
            "terms",
            f"{bad} need finite bounds: they decide the early-end penalty, which would be "
            f"infinite.",
        )
    if not (plant.term_low <= plant.term_high).all():
        bad = [t.name for t, lo, hi in zip(task.terms, plant.term_low, plant.term_high) if lo > hi]
        raise _fail(name, "terms", f"{bad}: low bound above high.")
    for label, lo, hi, _ in plant.columns:
        if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
            raise _fail(
                name,
                f"observation ({label})",
                f"bounds [{lo:.6g}, {hi:.6g}] must be finite with low <= high.",
            )
    _check_inputs(plant)
    _check_mass(plant)


def _check_inputs(plant) -> None:
    """Every actuated input moves something: a column of d(qddot)/du that is not zero at
    sample states (the accelerations are affine in the inputs, so one difference is exact)."""
    system, task = plant.system, plant.task
    x = plant.sample_states(8)
    u = np.zeros((len(x), system.n_u))
    a0 = system.accelerations(0.0, x, u)
    for k, j in enumerate(plant.actuated):
        e = u.copy()
        e[:, j] = 1.0
        if not np.any(system.accelerations(0.0, x, e) - a0):
            raise _fail(
                task.name,
                "actuated",
                f"drives {task.actuated[k]!r}, which appears in no generalised force of "
                f"{system.name}: the action would do nothing.",
            )


def _check_mass(plant) -> None:
    """The accelerations are defined at sample starts (a singular mass matrix means a
    coordinate without inertia, or degenerate constraints)."""
    x = plant.sample_states(8)
    try:
        plant.system.accelerations(0.0, x, np.zeros((len(x), plant.system.n_u)))
    except ValueError as exc:
        raise _fail(
            plant.task.name, "model", f"cannot be integrated from its starting states: {exc}"
        ) from None


def check_equilibrium(plant, x0: np.ndarray, u0: np.ndarray) -> None:
    """ValueError unless inputs within the declared limits hold x0 with zero accelerations
    (a time-dependent model is checked by the agents that need it)."""
    system, name = plant.system, plant.task.name
    acc = system.accelerations(0.0, x0, u0)
    scale = max(1.0, float(np.abs(system.accelerations(0.0, x0, np.zeros_like(u0))).max()))
    worst = float(np.abs(acc).max())
    if worst > 1e-8 * scale:
        raise _fail(
            name,
            "operating_point",
            f"is no equilibrium: the best inputs within reach leave accelerations of up to "
            f"{worst:.3g} (in units of the state's rates per second) at x0 = "
            f"{np.round(x0, 6).tolist()}.",
        )
    low, high = plant.input_low, plant.input_high
    ua = u0[..., plant.actuated]
    over = (ua < low - 1e-9 * np.abs(low)) | (ua > high + 1e-9 * np.abs(high))
    if over.any():
        k = int(np.argwhere(over)[0][-1])
        raise _fail(
            name,
            "operating_point",
            f"needs input {plant.task.actuated[k]!r} = {float(np.ravel(ua[..., k])[0]):.6g}, "
            f"outside its limits [{low[k]:.6g}, {high[k]:.6g}].",
        )


# ---- the task's functions, once as numpy ---------------------------------------------------
def _read_only(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=np.float64)
    a.setflags(write=False)
    return a


def _call(task_name: str, label: str, fn: Callable, args):
    try:
        with np.errstate(all="ignore"):
            return fn(*args)
    except IndexError as exc:
        raise IndexError(
            f"Task {task_name!r}: {label} indexes beyond its inputs on sample rows ({exc})."
        ) from None
    except ValueError as exc:
        if "read-only" in str(exc):
            raise DeclarationError(
                f"Task {task_name!r}: {label} writes into its inputs ({exc}); compute new "
                f"arrays instead (`err = x - 0.5`, not `err -= 0.5` on a column)."
            ) from None
        raise DeclarationError(f"Task {task_name!r}: {label} fails on sample rows: {exc}") from exc
    except Exception as exc:
        raise DeclarationError(
            f"Task {task_name!r}: {label} fails on sample rows: {type(exc).__name__}: {exc}"
        ) from exc


def _column(task_name: str, label: str, value, n: int, kind: str) -> np.ndarray:
    v = np.asarray(value)
    if v.shape == () and kind == "real":
        v = np.broadcast_to(v, (n,))
    if v.shape != (n,):
        raise DeclarationError(
            f"Task {task_name!r}: {label} must give one value per row, shape ({n},); got shape "
            f"{v.shape}."
        )
    if kind == "bool":
        if v.dtype != np.bool_:
            raise DeclarationError(
                f"Task {task_name!r}: {label} must give booleans (a comparison), got dtype "
                f"{v.dtype}."
            )
        return v
    if v.dtype.kind not in "fiu":
        raise DeclarationError(
            f"Task {task_name!r}: {label} must give real numbers, got dtype {v.dtype}."
        )
    if not np.isfinite(v).all():
        raise DeclarationError(
            f"Task {task_name!r}: {label} gives NaN or inf on sample rows (row "
            f"{int(np.flatnonzero(~np.isfinite(v))[0])})."
        )
    return v


def trial_run(plant, functions) -> None:
    """Each task function once as plain numpy on sample rows (read-only inputs): shapes,
    dtypes, term count, finiteness, booleans. `functions`: role -> (label, fn) with fn in
    the runtime's positional (x, a, g, p) form; roles 'reward' (the former form) or
    'term_k', 'success', 'failure', 'derived_k'."""
    name = plant.task.name
    rows, g = plant.sample_rows(8)
    n = len(rows)
    rng = np.random.default_rng(0)
    a = rng.uniform(-1.0, 1.0, (n, len(plant.actuated)))
    args = (_read_only(rows), _read_only(a), _read_only(g), plant.p)
    for role, (label, fn) in functions.items():
        out = _call(name, label, fn, args)
        if role == "reward":
            terms = plant.task.terms
            if not isinstance(out, (tuple, list)) or len(out) != len(terms):
                got = len(out) if isinstance(out, (tuple, list)) else type(out).__name__
                raise DeclarationError(
                    f"Task {name!r}: {label} must return {len(terms)} terms "
                    f"{tuple(t.name for t in terms)} as a tuple, got {got}."
                )
            for t, v in zip(terms, out):
                _column(name, f"{label} term {t.name!r}", v, n, "real")
        elif role in ("success", "failure"):
            _column(name, label, out, n, "bool")
        else:
            _column(name, label, out, n, "real")
