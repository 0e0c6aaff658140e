"""The task's functions compiled for a runtime's step (`envs.step`): each with numba when
numba can type it (bounds-checked, cached on disk), else as plain Python with a warning,
and bound to the machine code for the runtime's own arrays (`bind`). Functions only: the
step owns what they return."""

from __future__ import annotations

import warnings

import numpy as np

from dynamics.cache import cache_function

from . import checks, names
from .task import Derived

_COMPILED: dict = {}


def name_of(fn) -> str:
    return getattr(fn, "__qualname__", repr(fn))


def compile_task_function(fn, args):
    """`fn` compiled with numba, bounds-checked (an index slip raises IndexError, never
    reads another buffer) and cached on disk in the model cache (`dynamics.cache.
    cache_function`, not beside the user's source), or `fn` itself when
    numba cannot type it; `args` is a sample call used to find out."""
    key = (fn, tuple(type(a) for a in args))
    if key in _COMPILED:
        return _COMPILED[key]
    import numba

    compiled = fn
    errors = []
    for cache in (True, False):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", numba.NumbaWarning)
                jitted = numba.njit(boundscheck=True)(fn)
                if cache:  # numba's files in the model cache, not the user's __pycache__
                    cache_function(jitted, fn)
                signature = tuple(as_fused(numba.typeof(a)) for a in args)
                jitted.compile(signature)  # the types the fused step calls it with
                jitted.overloads[signature].entry_point(*args)
            compiled = jitted
            break
        except Exception as exc:  # numba's typing errors have no common public base
            errors.append(exc)
    if compiled is fn:
        first = str(errors[-1]).strip().splitlines()[0] if errors else ""
        warnings.warn(
            f"Task function {getattr(fn, '__qualname__', fn)!r} runs as plain Python (numba "
            f"could not compile it: {first}). It works, only slower per step.",
            RuntimeWarning,
            stacklevel=3,
        )
    _COMPILED[key] = compiled
    return compiled


def _entry(fn, args):
    """The machine code of compiled `fn` for the types the fused step calls it with
    (`as_fused`), called without numba's type dispatch (see `bind`), or `fn` itself.
    The step of separate calls then runs the very code the fused step links, whatever the
    layout of its columns (a single row's are contiguous): nothing more to compile."""
    overloads = getattr(fn, "overloads", None)
    if overloads is None:
        return fn
    import numba

    compiled = overloads.get(tuple(as_fused(numba.typeof(a)) for a in args))
    return fn if compiled is None else compiled.entry_point


def as_fused(argument_type):
    """The type the fused step gives an argument of `argument_type`: its named columns
    are column views (layout 'A'), which a single row's sample (contiguous) is not. So
    the function compiles once, not once for the sample and again for the fused step."""
    from numba.core import types

    if not isinstance(argument_type, types.BaseNamedTuple):
        return argument_type
    fields = [t.copy(layout="A") if isinstance(t, types.Array) else t for t in argument_type]
    return types.BaseTuple.from_types(fields, argument_type.instance_class)


def bind(fn, args):
    """The machine code numba compiled of `fn` for the types of `args`, called without
    numba's per-call type dispatch (about a microsecond for the parameter record, more
    than the work of one row): for the runtime's own arrays, whose types never change.
    `fn` itself when it is plain Python or has no overload for those types."""
    overloads = getattr(fn, "overloads", None)
    if overloads is None:
        return fn
    compiled = overloads.get(tuple(fn.typeof_pyval(a) for a in args))
    return fn if compiled is None else compiled.entry_point


def warm(kernel, *args):
    """`kernel` bound (see `bind`) after one call on copies of `args`."""
    kernel(*(a.copy() if isinstance(a, np.ndarray) else a for a in args))
    return bind(kernel, args)


def pack(constants, dtype):
    """[(name, start, size, shape or None for a scalar)] and the values in one flat array."""
    table, parts, start = [], [], 0
    for name, value in constants:
        v = np.asarray(value, dtype=dtype)
        table.append((name, start, v.size, None if v.ndim == 0 else v.shape))
        parts.append(v.ravel())
        start += v.size
    return table, np.concatenate(parts)


def _functions(plant) -> dict:
    """role -> (label, fn): the task's functions, one per reward term ('term_k'), then
    'success', 'failure' and 'derived_k'."""
    task = plant.task
    out = {}
    for k, t in enumerate(task.terms):
        out[f"term_{k}"] = (f"term {t.name!r} ({name_of(t.fn)})", t.fn)
    out["success"] = (f"success ({name_of(task.success)})", task.success)
    if task.failure is not None:
        out["failure"] = (f"failure ({name_of(task.failure)})", task.failure)
    features = [f for f in task.observation if isinstance(f, Derived)]
    for k, ((_, fn), f) in enumerate(zip(plant.derived, features)):
        out[f"derived_{k}"] = (f"Derived({f.name!r}) ({name_of(fn)})", fn)
    return out


def compile_functions(plant, arrays, task_params):
    """(types, callers, compiled) of `plant`'s task functions, each run once on sample
    rows (`envs.checks.trial_run`), then compiled (`compile_task_function`) for the rows'
    `arrays` and `task_params`: types, the named inputs' record classes (rows, actions,
    goal); callers, 'reward' (every term's values), 'success', 'failure' (or None) and
    'derived' ([(column, fn)]), each taking (x, a, g, p) as arrays; compiled, the numba
    functions by role ('_term_0', ...), for the fused step."""
    task = plant.task
    functions = _functions(plant)
    types = (
        names.record_type("Rows", plant.row_names),
        names.record_type("Actions", task.actuated),
        names.record_type("Goal", plant.goal_names),
    )
    positional = {
        role: (label, names.caller(fn, *types)) for role, (label, fn) in functions.items()
    }
    checks.trial_run(plant, positional)
    rows = (arrays.rows_x, arrays.A, arrays.G)
    sample = (*(names.columns(cls, a) for cls, a in zip(types, rows)), task_params)
    jitted = {f"_{r}": compile_task_function(fn, sample) for r, (_, fn) in functions.items()}
    callers = {r: names.caller(_entry(jitted[f"_{r}"], sample), *types) for r in functions}
    term_calls = [callers[r] for r in functions if r.startswith("term_")]
    return (
        types,
        {
            "reward": lambda x, a, g, p: [f(x, a, g, p) for f in term_calls],
            "success": callers["success"],
            "failure": callers.get("failure"),
            "derived": [(col, callers[f"derived_{k}"]) for k, (col, _) in enumerate(plant.derived)],
        },
        jitted,
    )


def actions_type():
    """The one type the fused step takes its actions as: float64, 2-d, any layout,
    read-only. The runtime gives it float64 (`Runtime.step`), and C or Fortran order, a
    view or a read-only array all pass as they are, so a task's step compiles once, not
    once per kind of array a caller holds."""
    from numba.core import types

    return types.Array(types.float64, 2, "A", readonly=True)
