"""The batched runtime: N rows of one task on one compiled system.

`Runtime` owns the state, goal, input and result arrays of N copies and offers two
operations, `reset_rows` (chosen rows to given states and goals) and `step` (every row by
one control period). The single env is a runtime of one row and the native vector env one
of N rows, each a thin Gymnasium wrapper; nothing else touches these arrays.

Per step: clip and scale the actions, the task's integrator (RK4 or DOP853 substeps,
spread over `num_threads`) through the compiled system, check every row for
divergence, then evaluate the task on the post-step state: the observation (one kernel for
the declared features, then each derived feature), the reward terms (clipped into their
declared bounds and summed), success and failure. A row that fails or diverges terminates,
and its reward carries the early-end penalty of `envs.task.Task`.

The task's own functions are compiled with numba here when numba can type them, and called
as plain Python otherwise (a warning says so once per function). When all of them compile
and one thread steps the rows, the whole step is one compiled call (`envs.fused`), with the
same results bit for bit: the per-row arrays are views of a few flat buffers for that.

The env's own runtime (`perturbed=True`) applies the plant's perturbations (`envs.perturb`):
before a step, the inputs applied and the pushes' generalised forces replace the commanded
inputs (a variant of the fused step takes them); after it, the observation handed out gets
its noise. Other runtimes of the plant (`env.simulator(n)`) step the nominal plant.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
from numba import njit

from dynamics.system import BLOCK, method_tableau

from . import checks, fused, names
from .perturb import Perturber
from .plant import Plant
from .randomize import record_rows, task_records
from .task import Derived

_COMPILED: dict = {}


def _name(fn) -> str:
    return getattr(fn, "__qualname__", repr(fn))


def _derived_features(task):
    return [f for f in task.observation if isinstance(f, Derived)]


class NonFiniteActions(ValueError):
    """`Runtime.step` was given a NaN or inf action (nothing was changed)."""


def compile_task_function(fn, args):
    """`fn` compiled with numba, bounds-checked (an index slip raises IndexError, never
    reads another buffer) and cached on disk when its module allows, or `fn` itself when
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
                jitted = numba.njit(cache=cache, boundscheck=True)(fn)
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


def _warm(kernel, *args):
    """`kernel` bound (see `bind`) after one call on copies of `args`."""
    kernel(*(a.copy() if isinstance(a, np.ndarray) else a for a in args))
    return bind(kernel, args)


@njit(cache=True)
def apply_actions(actions, input_mid, input_half, actuated, clipped, U) -> bool:
    """Clip actions to [-1, 1] into `clipped` and map them into the actuated columns of
    the input rows U (input = mid + action * half: action -1 and 1 are the input's
    limits); False (and nothing written) if any action is NaN or inf."""
    for b in range(actions.shape[0]):
        for j in range(actions.shape[1]):
            if not np.isfinite(actions[b, j]):
                return False
    for b in range(actions.shape[0]):
        for j in range(actions.shape[1]):
            a = min(max(actions[b, j], -1.0), 1.0)
            clipped[b, j] = a
            U[b, actuated[j]] = input_mid[j] + a * input_half[j]
    return True


@njit(cache=True)
def advance(X, X_next, limits, diverged, T, dt, steps, horizon, steps_left) -> bool:
    """After a step into X_next: time and step counts, the steps left to `horizon` (none
    when it is negative: no time limit), X = X_next row by row except where X_next is not
    finite (that row keeps its previous, finite, state), and diverged[b] = some
    |X_next[b, i]| > limits[i] or non-finite. Whether any row diverged."""
    any_bad = False
    for b in range(X.shape[0]):
        T[b] += dt
        steps[b] += 1
        steps_left[b] = max(horizon - steps[b], 0) if horizon >= 0 else 0.0
        bad = False
        finite = True
        for i in range(X.shape[1]):
            v = X_next[b, i]
            if not np.isfinite(v):
                finite = False
                bad = True
            elif abs(v) > limits[i]:
                bad = True
        if finite:
            for i in range(X.shape[1]):
                X[b, i] = X_next[b, i]
        diverged[b] = bad
        any_bad |= bad
    return any_bad


@njit(cache=True)
def observe(X, G, ops, low, high, out) -> None:
    """The declared (non-derived) observation columns of every row, clipped to bounds:
    ops rows are (column, op, source, second source); a source indexes [X | G]."""
    nx = X.shape[1]
    for b in range(X.shape[0]):
        for k in range(ops.shape[0]):
            col, op, s, s2 = ops[k, 0], ops[k, 1], ops[k, 2], ops[k, 3]
            v = X[b, s] if s < nx else G[b, s - nx]
            if op == 0:
                r = v
            elif op == 1:
                r = math.cos(v)
            elif op == 2:
                r = math.sin(v)
            else:
                w = X[b, s2] if s2 < nx else G[b, s2 - nx]
                d = v - w
                r = math.cos(d) if op == 3 else math.sin(d)
            out[b, col] = min(max(r, low[col]), high[col])


@njit(cache=True)
def finish(terms, low, high, failed, diverged, steps_left, lowest, rewards, terminated,
           success, obs, obs_low, obs32) -> bool:  # fmt: skip
    """Clip each reward term into its bounds and sum them; a row terminates when it failed
    or diverged, and then adds the early-end penalty steps_left * min(0, lowest) and is no
    success; the observation is handed out as float32. A NaN or inf reward term or
    observation (a task function's) counts as divergence: the value becomes its lower
    bound, so nothing non-finite reaches the agent. Whether that happened to some row."""
    penalty = min(0.0, lowest)
    any_bad = False
    for b in range(terms.shape[0]):
        r = 0.0
        bad = False
        for k in range(terms.shape[1]):
            v = terms[b, k]
            if not np.isfinite(v):
                bad = True
                v = low[k]
            v = min(max(v, low[k]), high[k])
            terms[b, k] = v
            r += v
        for j in range(obs.shape[1]):
            if not np.isfinite(obs[b, j]):
                bad = True
                obs[b, j] = obs_low[j]
        if bad:
            diverged[b] = True
            any_bad = True
        ended = failed[b] or diverged[b]
        terminated[b] = ended
        if ended:
            r += steps_left[b] * penalty
            success[b] = False
        rewards[b] = r
        for j in range(obs.shape[1]):
            obs32[b, j] = obs[b, j]
    return any_bad


def _pack(constants, dtype):
    """[(name, start, size, shape or None for a scalar)] and the values in one flat array."""
    table, parts, start = [], [], 0
    for name, value in constants:
        v = np.asarray(value, dtype=dtype)
        table.append((name, start, v.size, None if v.ndim == 0 else v.shape))
        parts.append(v.ravel())
        start += v.size
    return table, np.concatenate(parts)


class Runtime:
    """N rows of a task (see the module docstring). Public arrays are read-only views for
    wrappers; `reset_rows` and `step` are the only writers."""

    def __init__(self, plant: Plant, n: int, *legacy, perturbed: bool = False):
        if legacy:  # the former (layout, n, control_period, substeps, integrator, threads)
            names = ("control_period", "substeps", "integrator", "num_threads")
            plant = dataclasses.replace(plant, **dict(zip(names, legacy)))
        self.plant = layout = plant
        self.system = s = plant.system
        self.n = n
        self.control_period = plant.control_period
        self.substeps = plant.substeps
        self.integrator = plant.integrator
        self.num_threads = plant.num_threads
        n_x, n_rows = s.state_size, len(layout.row_names)
        # every per-row array is a view of one of three flat buffers (float64, bool, and
        # the step counts), so that the fused step takes them in a few arguments
        self._floats = (
            ("X", n_x), ("_X_next", n_x), ("U", s.n_u), ("T", None),
            ("G", len(layout.goal_names)), ("A", len(layout.actuated)),
            ("_obs64", layout.obs_size), ("Q", len(layout.task.terms)), ("R", None),
            ("_rows_x", n_rows), ("_Y", len(s.output_names)), ("_steps_left", None),
            ("_E", 2), ("_C", s.n_c),
        )  # fmt: skip
        self._bools = ("terminated", "success", "diverged", "_failed")
        width = sum(1 if w is None else w for _, w in self._floats)
        self._F = np.zeros(n * width)
        self._B = np.zeros(n * len(self._bools), dtype=np.bool_)
        self.steps = np.zeros(n, dtype=np.int64)
        self.O = np.zeros((n, layout.obs_size), dtype=np.float32)
        # each row's own model parameters (columns: system.parameters), when the plant
        # declares randomisation; else None and every row steps with the system's own
        self.per_row = layout.randomize is not None
        self.P = np.tile(s.kernels()[1], (n, 1)) if self.per_row else None
        self.given = np.zeros(self.P.shape, dtype=bool) if self.per_row else None  # by reset
        self.drawn = np.zeros(n, dtype=bool) if self.per_row else None  # once-only draws made
        # each row's record `p` for the task functions, when it follows the row's values
        follows = self.per_row and getattr(layout, "p_follows", False)
        self.p_rows = record_rows(layout.p, n) if follows else None
        self._params: dict = {}  # `params` of a row (None: all), until `set_params`
        # the plant's perturbations (envs.perturb), applied only by the env's own runtime
        self.perturber = Perturber(plant.perturb, plant, n) if perturbed and plant.perturb else None
        self._views()
        self._compile()
        if self.per_row and len(layout.context):  # observed parameters: the env's values
            self.set_params(slice(None), self.P.copy())

    @property
    def layout(self) -> Plant:
        """Former name of `plant`."""
        return self.plant

    def _segments(self):
        """(name, start, width or None for one value a row) of each float array in _F,
        whose rows start..start + width (times n) it occupies."""
        start = 0
        for name, w in self._floats:
            yield name, start, w
            start += 1 if w is None else w

    def _views(self) -> None:
        """The per-row arrays as views of the flat buffers (see __init__)."""
        n = self.n
        for name, start, w in self._segments():
            view = self._F[n * start : n * (start + (1 if w is None else w))]
            setattr(self, name, view if w is None else view.reshape(n, w))
        for k, name in enumerate(self._bools):
            setattr(self, name, self._B[n * k : n * (k + 1)])
        self._E0 = self._E[0]  # row views for the single env's info, stable: never swapped

    def _plan(self):
        """(plan, constants as float64, constants as int64) of the fused step."""
        lay, s = self.plant, self.system
        a, w, c = method_tableau(self.integrator)
        # the generated step names each array as the runtime does, less the underscore
        floats = [(name.lstrip("_"), start, w) for name, start, w in self._segments()]
        bools = [(name.lstrip("_"), k) for k, name in enumerate(self._bools)]
        h = self.control_period / self.substeps
        real = [("input_mid", lay.input_mid), ("input_half", lay.input_half),
                ("limits", lay.limits), ("obs_low", lay.obs_low),
                ("obs_high", lay.obs_high), ("term_low", lay.term_low),
                ("term_high", lay.term_high), ("ta", a), ("tw", w), ("tc", c), ("h", h),
                ("dt", self.control_period), ("lowest", self._lowest)]  # fmt: skip
        whole = [("actuated", lay.actuated), ("ops", lay.ops), ("output_index", lay.output_index),
                 ("substeps", self.substeps), ("block", BLOCK)]  # fmt: skip
        real_constants, C = _pack(real, np.float64)
        whole_constants, K = _pack(whole, np.int64)
        plan = {
            "model_key": s.kernels()[0].KEY,
            "floats": floats,
            "bools": bools,
            "constants": real_constants + whole_constants,
            "integer_constants": {k for k, _ in whole},
            "outputs": list(lay.output_index),
            "n_x": s.state_size,
            "n_obs": lay.obs_size,
            "derived": [col for col, _ in lay.derived],
            "n_terms": len(lay.task.terms),
            "failure": lay.task.failure is not None,
            "named": lay.task.named,
            "widths": (len(lay.row_names), len(lay.actuated), len(lay.goal_names)),
            "types": [cls.__name__ for cls in self._types],
        }
        return plan, C, K

    def _compile_fused(self, compiled_functions: dict) -> None:
        """The fused step (envs.fused), when every task function is compiled and one
        thread steps the rows; else None (the step of separate calls)."""
        self._fused = None
        self._fused_bound: dict = {}
        if self.num_threads > 1 and self.n > BLOCK:
            return
        if not all(hasattr(f, "py_func") for f in compiled_functions.values()):
            return
        module, _ = self.system.kernels()
        pushed = self._pushed
        rows = self.per_row or pushed  # each row's own parameters: the kernels that read them so
        functions = {
            "_apply": apply_actions, "_advance": advance, "_observe": observe, "_finish": finish,
            "_erk": module.erk_rows, "_outputs": module.outputs_batch,
            **compiled_functions,
        }  # fmt: skip
        plan, self._fused_C, self._fused_K = self._plan()
        plan["perturbed"], plan["pushed"], plan["rows"] = self.perturber is not None, pushed, rows
        types = dict(zip(("_Rows", "_Actions", "_Goal"), self._types))
        self._fused = fused.build(plan, functions, types)

    def _task_functions(self) -> dict:
        """role -> (label, fn, named): the task's functions; a named task has one reward
        function per term ('term_k'), a task of the former form one 'reward'."""
        task, plant = self.plant.task, self.plant
        out = {}
        if task.named:
            for k, t in enumerate(task.terms):
                out[f"term_{k}"] = (f"term {t.name!r} ({_name(t.fn)})", t.fn)
        else:
            out["reward"] = (f"reward ({_name(task.reward)})", task.reward)
        out["success"] = (f"success ({_name(task.success)})", task.success)
        if task.failure is not None:
            out["failure"] = (f"failure ({_name(task.failure)})", task.failure)
        for k, ((_, fn), f) in enumerate(zip(plant.derived, _derived_features(task))):
            out[f"derived_{k}"] = (f"Derived({f.name!r}) ({_name(fn)})", fn)
        return out

    def _compile(self) -> None:
        lay = self.plant
        task = lay.task
        functions = self._task_functions()
        named = task.named
        self._types = (
            names.record_type("Rows", lay.row_names),
            names.record_type("Actions", task.actuated),
            names.record_type("Goal", lay.goal_names),
        )
        positional = {
            role: (label, names.caller(fn, *self._types) if named else fn)
            for role, (label, fn) in functions.items()
        }
        checks.trial_run(lay, positional)

        # the record the task functions read: the plant's, or one per row (p_rows)
        self._p_task = lay.p if self.p_rows is None else self.p_rows
        sample = (self._rows_x, self.A, self.G, self._p_task)
        if named:
            sample_named = (
                *(names.columns(cls, a) for cls, a in zip(self._types, sample[:3])),
                self._p_task,
            )
            jitted = {
                f"_{r}": compile_task_function(fn, sample_named) for r, (_, fn) in functions.items()
            }
            calls = {r: names.caller(jitted[f"_{r}"], *self._types) for r in functions}
            term_calls = [calls[r] for r in functions if r.startswith("term_")]
            self._reward = lambda x, a, g, p: [f(x, a, g, p) for f in term_calls]
            self._success = calls["success"]
            self._failure = calls.get("failure")
            self._derived = [(col, calls[f"derived_{k}"]) for k, (col, _) in enumerate(lay.derived)]
        else:
            jitted = {
                f"_{r}": compile_task_function(fn, sample) for r, (_, fn) in functions.items()
            }
            self._reward = bind(jitted["_reward"], sample)
            self._success = bind(jitted["_success"], sample)
            self._failure = None if task.failure is None else bind(jitted["_failure"], sample)
            self._derived = [
                (col, bind(jitted[f"_derived_{k}"], sample))
                for k, (col, _) in enumerate(lay.derived)
            ]
        self._lowest = float(lay.lowest_reward)
        self._term_names = [t.name for t in task.terms]
        # the kernels on the runtime's own arrays (bound after a call on copies, which
        # compiles or loads them for exactly these types)
        self._observe = _warm(observe, self._rows_x, self.G, lay.ops, lay.obs_low,
                              lay.obs_high, self._obs64)  # fmt: skip
        self._advance = _warm(advance, self.X, self._X_next, lay.limits, self.diverged,
                              self.T, 0.0, self.steps, -1, self._steps_left)  # fmt: skip
        self._finish = _warm(finish, self.Q, lay.term_low, lay.term_high, self._failed,
                             self.diverged, self._steps_left, self._lowest, self.R,
                             self.terminated, self.success, self._obs64, lay.obs_low,
                             self.O)  # fmt: skip
        module, self._p_model = self.system.kernels()
        # what the model's kernels take as parameters: the system's, or each row's own
        self._p_kernel = self.P if self.per_row else self._p_model
        # pushes step through the integrator that adds forces, which reads rows' parameters
        self._pushed = self.perturber is not None and self.perturber.spec.push is not None
        self._p_step = self.perturber.P if self._pushed and not self.per_row else self._p_kernel
        self._energy = _warm(module.energy_batch, self.T, self.X, self._p_model, self.P, self._E)
        self._compile_fused(jitted)

    # pickling: numba dispatchers are rebuilt (from numba's cache) rather than pickled
    def __getstate__(self):
        state = self.__dict__.copy()
        for k in ("_reward", "_success", "_failure", "_derived", "_observe", "_advance",
                  "_finish", "_fused", "_fused_bound", "_fused_C", "_fused_K", "_energy", "_types",
                  "_E0", "_p_kernel", "_p_step", "_p_task"):  # fmt: skip
            state.pop(k, None)
        for name in (*(f for f, _ in self._floats), *self._bools):  # views of the buffers
            state.pop(name)
        return state

    def __setstate__(self, state):
        state.setdefault("per_row", False)  # pickled before per-row parameters
        state.setdefault("P", None)
        state.setdefault("given", None)
        state.setdefault("p_rows", None)
        state.setdefault("drawn", None if state["P"] is None else np.ones(len(state["P"]), bool))
        state.setdefault("_params", {})
        state.setdefault("perturber", None)
        self.__dict__.update(state)
        self._views()
        self._compile()

    # ---- parameters -----------------------------------------------------------------------
    def set_params(self, rows, values: np.ndarray) -> None:
        """Rows `rows` step from now on with parameters `values` (len(rows), n_p), columns
        in the order of `system.parameters` (checked by the caller): a masked write,
        nothing recompiled."""
        if not self.per_row:
            raise ValueError(
                "This runtime steps every row with the system's parameters; build its plant "
                "with randomize= (randomize={} for exact values only) for per-row values."
            )
        self.P[rows] = values
        self._params = {}
        if self.p_rows is not None:  # the task functions' records, constants recomputed
            self.p_rows[rows] = task_records(self.plant, self.P[rows])
        context = getattr(self.plant, "context", ())  # observed parameters (add_context)
        for col, j in np.asarray(context).tolist():
            lo, hi = self.plant.obs_low[col], self.plant.obs_high[col]
            self._obs64[rows, col] = np.clip(self.P[rows, j], lo, hi)
            self.O[rows, col] = self._obs64[rows, col]

    def params(self, row: int | None = None) -> dict:
        """The parameter values in force: name -> float of one row, or (N,) read-only
        arrays (kept until `set_params`: a step's info costs no copies)."""
        if row in self._params:
            return dict(self._params[row])
        names = list(self.system.parameters)
        values = np.tile(self._p_model, (self.n, 1)) if self.P is None else self.P
        if row is not None:
            out = dict(zip(names, values[row].tolist()))
        else:
            out = {k: values[:, j].copy() for j, k in enumerate(names)}
            for v in out.values():
                v.flags.writeable = False
        self._params[row] = out
        return dict(out)

    # ---- the two operations --------------------------------------------------------------
    def reset_rows(self, rows, x: np.ndarray, g: np.ndarray) -> None:
        """Put `rows` at states x and goals g (time 0, no input), and evaluate them."""
        self.X[rows] = x
        self.G[rows] = g
        self.T[rows] = 0.0
        self.U[rows] = 0.0
        self.A[rows] = 0.0
        self.steps[rows] = 0
        self.diverged[rows] = False
        self.terminated[rows] = False
        self.success[rows] = False
        self.Q[rows] = 0.0
        self.R[rows] = 0.0
        lay = self.plant
        x, g, a = self.rows()[rows], self.G[rows], self.A[rows]
        obs = self._obs64[rows]  # a copy: every column is rewritten but the context's
        observe(x, g, lay.ops, lay.obs_low, lay.obs_high, obs)
        for col, fn in self._derived:
            obs[:, col] = fn(x, a, g, lay.p if self.p_rows is None else self.p_rows[rows])
        np.clip(obs, lay.obs_low, lay.obs_high, out=obs)
        self._obs64[rows] = obs
        self.O[rows] = obs
        if self.perturber is not None:
            index = np.arange(self.n)[rows]
            self.perturber.clear(index)
            self.perturber.observe(self._obs64, self.O, index)

    def step(self, actions: np.ndarray, horizon: int | None) -> bool:
        """Advance every row one control period under `actions` (N, n_a), finite; the
        early-end penalty counts the steps left to `horizon` (None: no time limit, no
        penalty). Returns whether any row diverged."""
        lay = self.plant
        perturbed = ()
        if self.perturber is not None:  # the inputs applied and the pushes (envs.perturb)
            if not np.isfinite(actions).all():
                raise NonFiniteActions("actions contain NaN or inf")
            perturbed = self.perturber.before_step(actions, self.T, self.X, self._p_step)
        if self._fused is not None:
            f = actions.flags
            step = self._fused_bound.get((actions.dtype, f.c_contiguous, f.writeable, f.aligned))
            if step is None:
                step = self._bind_fused(actions)
            code = step(actions, self._F, self._B, self.steps, self.O, self._fused_C,
                        self._fused_K, self._p_step, self._p_task,
                        -1 if horizon is None else horizon, *perturbed)  # fmt: skip
            if code < 0:
                raise NonFiniteActions("actions contain NaN or inf")
            if perturbed:
                self.perturber.observe(self._obs64, self.O)
            return code > 0
        if not apply_actions(actions, lay.input_mid, lay.input_half, lay.actuated, self.A, self.U):
            raise NonFiniteActions("actions contain NaN or inf")
        if perturbed:
            self.U[:, lay.actuated] = perturbed[0]
        if self._pushed:
            self.system.step_pushed_unchecked(
                self.T, self.X, self.U, self._p_step, perturbed[1], self.control_period,
                self.substeps, self._X_next, self.integrator,
            )  # fmt: skip
        elif self.per_row:
            self.system.step_rows_unchecked(
                self.T, self.X, self.U, self.P, self.control_period, self.substeps,
                self._X_next, self.integrator, self.num_threads,
            )  # fmt: skip
        else:
            self.system.step_unchecked(
                self.T, self.X, self.U, self.control_period, self.substeps, self._X_next,
                self.integrator, self.num_threads,
            )  # fmt: skip
        diverged = self._advance(self.X, self._X_next, lay.limits, self.diverged, self.T,
                                 self.control_period, self.steps,
                                 -1 if horizon is None else horizon, self._steps_left)  # fmt: skip
        bad = self._evaluate(self._steps_left)
        if perturbed:
            self.perturber.observe(self._obs64, self.O)
        return bool(diverged) or bool(bad)

    def _bind_fused(self, actions: np.ndarray):
        """The fused step's machine code for arrays like `actions` (compiled or loaded from
        numba's cache on first use), bound as `bind` does."""
        f = actions.flags
        args = (actions, self._F, self._B, self.steps, self.O, self._fused_C, self._fused_K,
                self._p_step, self._p_task, -1)  # fmt: skip
        if self.perturber is not None:  # samples of the applied inputs and the forces
            args += (self.perturber.applied, self.perturber.W)
        self._fused.compile(tuple(self._fused.typeof_pyval(a) for a in args))
        step = bind(self._fused, args)
        self._fused_bound[(actions.dtype, f.c_contiguous, f.writeable, f.aligned)] = step
        return step

    def _evaluate(self, steps_left: np.ndarray) -> bool:
        lay = self.plant
        x = self.rows()
        self._observe(x, self.G, lay.ops, lay.obs_low, lay.obs_high, self._obs64)
        if self._derived:  # the declared features are clipped by `observe` already
            for col, fn in self._derived:
                self._obs64[:, col] = fn(x, self.A, self.G, self._p_task)
            np.clip(self._obs64, lay.obs_low, lay.obs_high, out=self._obs64)
        for k, v in enumerate(self._reward(x, self.A, self.G, self._p_task)):
            self.Q[:, k] = v
        self.success[:] = self._success(x, self.A, self.G, self._p_task)
        if self._failure is not None:
            self._failed[:] = self._failure(x, self.A, self.G, self._p_task)
        return self._finish(self.Q, lay.term_low, lay.term_high, self._failed,
                            self.diverged, steps_left, self._lowest, self.R,
                            self.terminated, self.success, self._obs64, lay.obs_low,
                            self.O)  # fmt: skip

    def rows(self) -> np.ndarray:
        """The rows the task functions see: the state, then the declared model outputs."""
        lay = self.plant
        if not len(lay.output_index):
            return self.X
        if self.per_row:
            m = self.system.kernels()[0]
            m.outputs_batch(self.T, self.X, self.U, self._p_model, self.P, self._Y)
        else:
            self.system.outputs_unchecked(self.T, self.X, self.U, self._Y)
        n_x = self.system.state_size
        self._rows_x[:, :n_x] = self.X
        self._rows_x[:, n_x:] = self._Y[:, lay.output_index]
        return self._rows_x

    # ---- diagnostics ---------------------------------------------------------------------
    def energy(self) -> np.ndarray:
        """T + V of every row, J."""
        self._energy(self.T, self.X, self._p_model, self.P, self._E)
        return self._E.sum(axis=1)

    def energy_of_row0(self) -> float:
        """T + V of the first row, J (the single env's cheap path)."""
        self._energy(self.T, self.X, self._p_model, self.P, self._E)
        kinetic, potential = self._E0.tolist()
        return kinetic + potential

    def constraint_residual(self) -> np.ndarray:
        """The velocity-constraint residual of every row (N, n_c)."""
        if self.per_row:
            m = self.system.kernels()[0]
            m.residual_batch(self.T, self.X, self._p_model, self.P, self._C)
        else:
            self.system.constraint_residual_unchecked(self.T, self.X, self._C)
        return self._C.copy()

    def reward_terms(self, row: int | None = None):
        """The clipped reward terms, by name: floats of one row, or arrays of every row."""
        names = self._term_names
        if row is None:
            return {k: self.Q[:, i].copy() for i, k in enumerate(names)}
        return dict(zip(names, self.Q[row].tolist()))
