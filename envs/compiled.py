"""The task's functions compiled for a runtime: each with numba when numba can type it
(bounds-checked, cached on disk), else as plain Python with a warning, and bound to the
machine code for the runtime's own arrays (`bind`)."""

from __future__ import annotations

import os
import threading
import warnings

import numpy as np

from dynamics import calls, stepping
from dynamics.cache import function_cache, keep_numba_cache_true
from dynamics.rows import outputs_batch
from dynamics.system import BLOCK, _kernel_compiled, method_tableau

from . import checks, fused, names
from .observation import observe
from .row_kernels import advance, apply_actions, finish
from .task import Derived

_COMPILED: dict = {}


def name_of(fn) -> str:
    return getattr(fn, "__qualname__", repr(fn))


def compile_task_function(fn, args):
    """`fn` compiled with numba, bounds-checked (an index slip raises IndexError, never
    reads another buffer) and cached on disk in the model cache (`dynamics.cache.
    function_cache`, not beside the user's source), or `fn` itself when
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
                    jitted._cache = function_cache(fn)
                    keep_numba_cache_true(jitted, fn)  # helpers' edits in other files
                signature = tuple(_as_fused(numba.typeof(a)) for a in args)
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
    (`_as_fused`), called without numba's type dispatch (see `bind`), or `fn` itself.
    The step of separate calls then runs the very code the fused step links, whatever the
    layout of its columns (a single row's are contiguous): nothing more to compile."""
    overloads = getattr(fn, "overloads", None)
    if overloads is None:
        return fn
    import numba

    compiled = overloads.get(tuple(_as_fused(numba.typeof(a)) for a in args))
    return fn if compiled is None else compiled.entry_point


def _as_fused(argument_type):
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


def _functions(rt) -> dict:
    """role -> (label, fn): the task's functions, one per reward term ('term_k'), then
    'success', 'failure' and 'derived_k'."""
    task, plant = rt.plant.task, rt.plant
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


def compile_functions(rt) -> dict:
    """The task's functions for runtime `rt`, each run once on sample rows
    (`envs.checks.trial_run`), then compiled (`compile_task_function`) and set as the
    runtime's `_reward`, `_success`, `_failure` and `_derived`; the compiled ones by role."""
    plant = rt.plant
    task = plant.task
    functions = _functions(rt)
    rt._types = (
        names.record_type("Rows", plant.row_names),
        names.record_type("Actions", task.actuated),
        names.record_type("Goal", plant.goal_names),
    )
    positional = {
        role: (label, names.caller(fn, *rt._types)) for role, (label, fn) in functions.items()
    }
    checks.trial_run(plant, positional)
    sample = (
        *(names.columns(cls, a) for cls, a in zip(rt._types, (rt._rows_x, rt.A, rt.G))),
        rt._task_params,
    )
    jitted = {f"_{r}": compile_task_function(fn, sample) for r, (_, fn) in functions.items()}
    callers = {r: names.caller(_entry(jitted[f"_{r}"], sample), *rt._types) for r in functions}
    term_calls = [callers[r] for r in functions if r.startswith("term_")]
    rt._reward = lambda x, a, g, p: [f(x, a, g, p) for f in term_calls]
    rt._success = callers["success"]
    rt._failure = callers.get("failure")
    rt._derived = [(col, callers[f"derived_{k}"]) for k, (col, _) in enumerate(plant.derived)]
    return jitted


def plan(rt, functions: dict):
    """(plan, constants as float64, constants as int64) of runtime `rt`'s fused step, which
    calls `functions` (role -> kernel) and the model's integrator through their addresses:
    `rt._calls` lists (slot in the int64 constants, kernel, argument types) for
    `bind_fused`."""
    plant, s = rt.plant, rt.system
    a, w, c = method_tableau(rt.integrator)
    # the generated step names each array as the runtime does, less the underscore
    floats = [(name.lstrip("_"), start, w) for name, start, w in rt._segments()]
    bools = [(name.lstrip("_"), k) for k, name in enumerate(rt._bools)]
    h = rt.control_period / rt.substeps
    real = [("input_mid", plant.input_mid), ("input_half", plant.input_half),
            ("limits", plant.limits), ("obs_low", plant.obs_low),
            ("obs_high", plant.obs_high), ("term_low", plant.term_low),
            ("term_high", plant.term_high), ("ta", a), ("tw", w), ("tc", c), ("h", h),
            ("dt", rt.control_period), ("lowest", rt._lowest)]  # fmt: skip
    roles = ["integrator", *functions]
    whole = [("actuated", plant.actuated), ("ops", plant.ops),
             ("output_index", plant.output_index), ("substeps", rt.substeps),
             ("block", BLOCK), ("addresses", np.zeros(len(roles))),
             ("model_kernels", np.zeros(stepping.TABLE_SIZE))]  # fmt: skip
    # addresses: of the kernels the step calls; model_kernels: the model's table, which the
    # integrator reads (dynamics.stepping); both written by bind_fused (dynamics.calls)
    real_constants, C = pack(real, np.float64)
    whole_constants, K = pack(whole, np.int64)
    plan = {
        "model_key": s.kernel_module.KEY,
        "floats": floats,
        "sizes": (sum(1 if w is None else w for *_, w in floats), len(bools), len(C), len(K)),
        "bools": bools,
        "constants": real_constants + whole_constants,
        "integer_constants": {k for k, _ in whole},
        "outputs": list(plant.output_index),
        "n_x": s.state_size,
        "n_obs": plant.obs_size,
        "derived": [col for col, _ in plant.derived],
        "n_terms": len(plant.task.terms),
        "failure": plant.task.failure is not None,
        "widths": (len(plant.row_names), len(plant.actuated), len(plant.goal_names)),
        "types": [cls.__name__ for cls in rt._types],
        "perturbed": rt.perturber is not None,
        "pushed": rt._pushed,
        "rows": rt.parameters.per_row,  # each row's own parameters
        "row_by_row": rt._row_by_row,  # erk_row, one row at a time; else erk_rows
    }
    at = next(start for name, start, *_ in whole_constants if name == "addresses")
    rt._table_slot = next(start for name, start, *_ in whole_constants
                           if name == "model_kernels")  # fmt: skip
    kinds = variable_types(rt, plan)
    rt._calls = [(at, *integrator(rt, kinds))]
    for role in functions:
        rt._calls.append((at + len(rt._calls), functions[role],
                          tuple(kinds[v] for v in fused.arguments(role))))  # fmt: skip
    plan["calls"] = {
        role: (slot - at, calls.label(kernel, types))
        for role, (slot, kernel, types) in zip(roles, rt._calls)
    }
    return plan, C, K


def variable_types(rt, plan: dict) -> dict:
    """The numba type of each variable of the generated step that a kernel takes: the
    runtime's arrays as views of the flat buffers (contiguous), the constants, the step's
    arguments and the named inputs (envs.fused.source)."""
    from numba import typeof
    from numba.core import types

    f8, i8 = types.float64, types.int64
    kinds = {
        "actions": actions_type(), "steps": typeof(rt.steps), "O": typeof(rt.O),
        "model_params": typeof(rt._model_params), "task_params": typeof(rt._task_params),
        "horizon": i8,
    }  # fmt: skip
    for name, _, width in plan["floats"]:
        kinds[fused.RENAMED.get(name, name)] = types.Array(f8, 1 if width is None else 2, "C")
    for name, _ in plan["bools"]:
        kinds[name] = types.Array(types.boolean, 1, "C")
    for name, _, _, shape in plan["constants"]:
        dtype = i8 if name in plan["integer_constants"] else f8
        kinds[name] = dtype if shape is None else types.Array(dtype, len(shape), "C")
    if rt.perturber is not None:  # the inputs applied and the pushes' forces
        kinds.update(applied=typeof(rt.perturber.applied), W=typeof(rt.perturber.W))
    params = kinds["model_params"]
    one = params.copy(ndim=1) if plan["rows"] else params  # a row's, or all rows
    kinds.update(one_params=one, row_params=params if plan["rows"] else types.none)
    kinds["x"] = kinds["rows_x" if plan["outputs"] else "X"]
    for var, cls in zip(("xs", "as_", "gs"), rt._types):  # columns of x, A and G by name
        kinds[var] = _as_fused(typeof(names.columns(cls, np.zeros((1, len(cls._fields))))))
    return kinds


def integrator(rt, kinds: dict):
    """(kernel, argument types) of the integrator as runtime `rt`'s fused step calls it
    (`kinds`: `variable_types`): `erk_row` one row at a time, or `erk_rows` a block at a
    time (see envs.fused), both of `dynamics.stepping`, with the model's table last."""
    from numba.core import types

    i8, table = types.int64, kinds["model_kernels"]
    head = tuple(kinds[v] for v in ("T", "X", "U", "one_params"))
    tableau = tuple(kinds[v] for v in ("h", "substeps", "ta", "tw", "tc", "X_next"))
    if rt._row_by_row:
        return stepping.erk_row, (*head, *tableau, i8, table)
    forces = kinds["W"] if rt._pushed else types.none
    return stepping.erk_rows, (*head, kinds["row_params"], forces, *tableau, i8, i8, table)


def model_kernels(rt) -> tuple[str, ...]:
    """The model's kernels runtime `rt`'s fused step calls through the integrator and
    `outputs_batch` (`dynamics.stepping.table`)."""
    if rt._row_by_row:
        lanes = ("derivative_lanes",)
    else:
        lanes = stepping.lane_kernels(rt.parameters.per_row, rt._pushed)
    return (*lanes, "accelerations", "outputs") if len(rt.plant.output_index) else lanes


def compile_fused(rt, jitted: dict) -> None:
    """Runtime `rt`'s fused step (envs.fused), when every task function is compiled and
    one thread steps the rows; else None (the step of separate calls)."""
    rt._fused = None
    rt._fused_bound = None
    if rt.num_threads > 1 and rt.n > BLOCK:
        return
    if not all(hasattr(f, "py_func") for f in jitted.values()):
        return
    functions = {"_apply": apply_actions, "_advance": advance}
    if len(rt.plant.output_index):
        functions["_outputs"] = outputs_batch
    functions.update(_observe=observe, **jitted, _finish=finish)
    plan_, rt._fused_C, rt._fused_K = plan(rt, functions)
    types = dict(zip(("_Rows", "_Actions", "_Goal"), rt._types))
    rt._fused = fused.build(plan_, functions, types)


def actions_type():
    """The one type the fused step takes its actions as: float64, 2-d, any layout,
    read-only. The runtime gives it float64 (`Runtime.step`), and C or Fortran order, a
    view or a read-only array all pass as they are, so a task's step compiles once, not
    once per kind of array a caller holds."""
    from numba.core import types

    return types.Array(types.float64, 2, "A", readonly=True)


def bind_fused(rt):
    """Runtime `rt`'s fused step's machine code (compiled or loaded from numba's cache on
    first use) for float64 actions of any layout (`actions_type`), bound as `bind` does."""
    at = rt._table_slot  # first the model's kernels, which the integrator calls
    table = stepping.table(rt.system.kernel_module, *model_kernels(rt))
    rt._fused_K[at : at + len(table)] = table
    for slot, kernel, types in rt._calls:  # compiled (or loaded) for the step's arguments
        rt._fused_K[slot] = calls.address(kernel, types)
    args = (rt._F, rt._B, rt.steps, rt.O, rt._fused_C, rt._fused_K, rt._model_params,
            rt._task_params, -1)  # fmt: skip
    if rt.perturber is not None:  # samples of the applied inputs and the forces
        args += (rt.perturber.applied, rt.perturber.W)
    signature = (actions_type(), *(rt._fused.typeof_pyval(a) for a in args))
    rt._fused.compile(signature)
    rt._fused_bound = rt._fused.overloads[signature].entry_point
    return rt._fused_bound


# ---- a new step compiled in the background -----------------------------------------------
_COMPILING: set[threading.Thread] = set()
SEPARATE_FIRST = 2_000
"""Steps a runtime takes by separate calls before its new fused step starts compiling: an
env stepped for an episode or a few (a check, a test, a look at a model) never compiles
it. The separate calls cost about 35 us a step more than the fused step (the arm and the
cart-pole here: 54 and 46 us against 17 and 13), so 0.07 s over these steps, against 2-3 s
of CPU to compile the step; a longer run compiles it once, for numba's cache."""


def fused_for(rt):
    """Runtime `rt`'s fused step, bound, or None while `Runtime.step` takes the step of
    separate calls: when numba's cache does not have the step, the runtime's first
    `SEPARATE_FIRST` steps are separate calls, and then the step compiles in a thread of
    its own while separate calls go on until it is bound. Both give the same results bit
    for bit, and by then the separate calls have run (so compiled) every kernel they use: a
    first call of a kernel while the thread compiles would wait for numba's compiler lock,
    that is for the whole step. So a new model's first step waits for its integrator, not
    for the fused step (about 2 s of compilation, mostly LLVM re-optimising what it
    links), and an env stepped a few times never compiles it. A thread that fails leaves
    its error to the next step, which binds the step itself."""
    pending = rt._fused_pending
    if pending is not None and pending.is_alive():
        return None
    if pending is not None or _kernel_compiled(rt._fused):
        return bind_fused(rt)
    rt._separate_steps += 1
    if rt._separate_steps <= SEPARATE_FIRST:
        return None
    thread = threading.Thread(target=_bind_quietly, args=(rt,), name="fused step")
    rt._fused_pending = thread
    _COMPILING.add(thread)
    thread.start()
    return None


def _bind_quietly(rt) -> None:
    try:
        bind_fused(rt)
    except Exception:  # noqa: S110 (the next step binds it again, and raises the error)
        pass
    finally:
        _COMPILING.discard(threading.current_thread())


def wait_for_background() -> None:
    """Wait until every fused step compiling in the background is bound (or has failed)."""
    for thread in list(_COMPILING):
        thread.join()


# a forked child would inherit numba's compiler lock held by a thread it does not have
os.register_at_fork(before=wait_for_background)
