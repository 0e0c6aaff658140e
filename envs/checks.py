"""Checks of what users hand in (make, reset, step) and of a declaration against its model.

`envs.task_checks.check_task` runs at `Task(...)` on what can be checked alone;
`check_with_model` runs when an env is made, on what needs the compiled model (names, ranges
inside limits, the operating point, the mass matrix, the inputs); `trial_run` calls the
task's functions once as plain numpy on sample rows, with read-only inputs, before the
runtime compiles them. The numbers and names themselves are checked by the one vocabulary,
`dynamics.checks` (real arrays, positive numbers, "Did you mean").
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping

import numpy as np

from dynamics.checks import did_you_mean, positive_float, positive_int, real_array

from . import names


class Unsupported(ValueError):
    """An agent that would be silently wrong on this plant refuses it (time-dependent
    dynamics for an agent designed at one time, coordinates the observation leaves out)."""


class DeclarationError(ValueError):
    """A task or model declaration that cannot work; the message names field and entry."""


def declaration_error(task_name: str, field: str, problem: str) -> DeclarationError:
    """The error of a task's declaration: "Task 'name': `field` problem" (raise it)."""
    return DeclarationError(f"Task {task_name!r}: `{field}` {problem}")


_fail = declaration_error


# ---- what users hand in at make, reset and step ---------------------------------------------
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


# ---- at make, with the model ---------------------------------------------------------------
def _known(task_name: str, field: str, names, known, what: str) -> None:
    for k in names:
        if k not in known:
            raise _fail(
                task_name,
                field,
                f"names unknown {what} {k!r}.{did_you_mean(k, known)} Known: {', '.join(known)}.",
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
                    f"names {v!r}, neither a goal component nor a parameter."
                    f"{did_you_mean(v, known)} Goals: {', '.join(plant.goal_names) or 'none'}; "
                    f"parameters: {', '.join(plant.p.dtype.names)}.",
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
    _check_goal_observed(plant)
    _check_starts(plant)
    _check_operating_point(plant)
    _check_inputs(plant)
    _check_mass(plant)


def _check_goal_observed(plant) -> None:
    """A goal component drawn at reset that the operating point needs (LQR, the heuristics
    and the hand-over regulate to it) must be read back from the observation: refused
    here, rather than when an agent first asks."""
    missing = plant.observation.goal_map[3]
    op = plant.task.operating_point
    if not missing or op is None:
        return
    needed = list(missing) if callable(op) else [g for g in missing if g in op.values()]
    if needed:
        raise _fail(
            plant.task.name,
            "observation",
            f"shows no goal component {', '.join(map(repr, needed))}, which is drawn at reset "
            "and which the operating point needs: no agent could tell the goal it should "
            "reach. Observe it (e.g. Value(name) or AngleError(state, goal)).",
        )


def _check_operating_point(plant) -> None:
    """An operating-point function, tried on sample goals and starts: one finite state per
    row (its slips surface here, not when an agent first asks)."""
    op = plant.task.operating_point
    if not callable(op):
        return
    named = names.named_operating_point(op)
    if not named:
        warnings.warn(
            names.FORMER_OPERATING_POINT.format(task=plant.task.name, fn=names.label(op)),
            DeprecationWarning,
            stacklevel=2,
        )
    rows, g = plant.sample_rows(4)
    x = rows[:, : len(plant.state_names)]
    try:
        with np.errstate(all="ignore"):
            x0 = plant.operating_state(g, x)
    except Exception as exc:  # the task's own function: any error is its slip
        form = "(x, goal, p)" if named else "the former form (g, x, system)"
        when = f", called in {form}, fails on sample rows"
        raise _slip(plant, "operating_point", op, when, exc) from None
    if x0.shape != x.shape or not np.isfinite(x0).all():
        raise _fail(
            plant.task.name,
            "operating_point",
            f"must give a finite state per row, shape {x.shape}; got shape {x0.shape}"
            + ("" if x0.shape != x.shape else " with NaN or inf")
            + ".",
        )


def _slip(plant, field: str, fn, when: str, exc: Exception) -> DeclarationError:
    """The one-line error of a start or operating-point function tried at make: what it
    raised (a misspelt field with a suggestion), or the check of what it returned."""
    text = str(exc)
    if text.startswith(f"Task {plant.task.name!r}"):  # envs.names' check of its names
        return DeclarationError(text)
    text = names.missing_field(exc, plant.p) or f"{type(exc).__name__}: {text}"
    return _fail(plant.task.name, field, f"function {names.label(fn)}{when}: {text}")


def _check_starts(plant) -> None:
    """The start distribution (a function's too, tried here on sample draws) gives states
    within the task's limits: one beyond would be observed clipped and end at once. A
    function's slips are named here, and its former form (arrays) warned of."""
    start = plant.task.start
    if callable(start):
        try:
            with np.errstate(all="ignore"):
                rng = np.random.default_rng(12345)
                named = names.start_values(plant, start(rng, plant.p), rng)[2]
        except Exception as exc:  # the task's own function: any error is its slip
            raise _slip(plant, "start", start, " fails on a sample draw", exc) from None
        if not named:
            warnings.warn(
                names.FORMER_START.format(task=plant.task.name, fn=names.label(start)),
                DeprecationWarning,
                stacklevel=2,
            )
    x = plant.sample_states(8)
    over = np.abs(x) > plant.limits
    if over.any():
        row, i = (int(v) for v in np.argwhere(over)[0])
        raise _fail(
            plant.task.name,
            "start",
            f"gives {plant.state_names[i]} = {x[row, i]:.6g}, beyond `limits"
            f"[{plant.state_names[i]!r}]` = {plant.limits[i]:.6g}: every such episode would "
            "end at once.",
        )


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
        text = names.missing_field(exc, args[-1] if isinstance(args[-1], np.record) else None)
        raise DeclarationError(
            f"Task {task_name!r}: {label} fails on sample rows: "
            + (text or f"{type(exc).__name__}: {exc}")
        ) from (None if text else exc)


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
    if "failure" in functions:
        from .region import check_region  # (which imports this module)

        check_region(plant, *functions["failure"])


__all__ = [
    "DeclarationError",
    "Unsupported",
    "check_equilibrium",
    "check_with_model",
    "checked_rows",
    "declaration_error",
    "positive_float",
    "positive_int",
    "real_array",
    "trial_run",
]
