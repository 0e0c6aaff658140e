"""The batched runtime: N rows of one task on one compiled system.

`Runtime` owns the state, goal, input and result arrays of N copies and their
parameter store (`envs.parameters.ParameterRows`), and offers the operations that write
them: `start` (what rows start an episode with, changing nothing), `begin` (put rows
there: their parameters, then `reset_rows`), `step` (every row by one control period) and
`redraw` (the mid-episode parameter redraws due). The single env is a runtime of one row
and the native vector env one of N rows, each a thin Gymnasium wrapper; nothing else
writes these arrays (docs/architecture.md names the writer of each).

Per step: clip and scale the actions, the task's integrator (RK4 or DOP853 substeps,
spread over `num_threads`) through the compiled system, check every row for
divergence, then evaluate the task on the post-step state: the observation (one kernel for
the declared features, then each derived feature), the reward terms (clipped into their
declared bounds and summed), success and failure. A row that fails or diverges terminates,
and its reward carries the early-end penalty of `envs.task.Task`.

The task's own functions are compiled with numba when numba can type them, and called as
plain Python otherwise (a warning says so once per function; `envs.compiled`). When all
of them compile and one thread steps the rows, the whole step is one compiled call
(`envs.fused`), with the same results bit for bit: the per-row arrays are views of a few
flat buffers for that. A new task's fused step compiles in a thread after the first steps,
which separate calls take (`envs.compiled.fused_for`). The
model's kernels read the store's `model_params`, the task's functions its `task_params`;
nothing reaches back for a parameter.

The env's own runtime (`perturbed=True`) applies the plant's perturbations (`envs.perturb`):
before a step, the inputs applied and the pushes' generalised forces replace the commanded
inputs (a variant of the fused step takes them); after it, the observation handed out gets
its noise. Other runtimes of the plant (`env.simulator(n)`) step the nominal plant.
"""

from __future__ import annotations

import numpy as np

from dynamics import stepping
from dynamics.rows import outputs_batch, state_batch
from dynamics.system import _kernel_compiled, method_tableau

from . import compiled
from .observation import observe
from .parameters import ParameterRows
from .perturb import Perturber
from .plant import Plant
from .row_kernels import advance, apply_actions, finish

ONE_BY_ONE = 64
"""Rows a vector env steps one at a time before its fused step is bound (see `_integrate`):
for at most 2,000 steps (`compiled.SEPARATE_FIRST`), about 6 us a row more than the lanes
(the arm: 521 against 146 us a step at 64 rows, so at most 0.8 s over those steps), against
compiling in the main thread what the lanes need and `erk_row` does not: the integrator's
lanes (once per machine, 1.5-2 s of CPU) and, for rows with their own parameters, the
model's `derivative_lanes_p` (0.3-1.3 s); the fused step's thread compiles them."""


class NonFiniteActions(ValueError):
    """`Runtime.step` was given a NaN or inf action (nothing was changed)."""


class Runtime:
    """N rows of a task (see the module docstring). Public arrays are read-only views for
    wrappers; the runtime's own methods are their only writers."""

    _FLOATS = ("X", "_X_next", "U", "T", "G", "A", "_obs64", "terms", "R", "_rows_x", "_Y",
               "_steps_left", "_E", "_C")  # fmt: skip
    _BOOLS = ("terminated", "success", "diverged", "_failed")

    def __init__(self, plant: Plant, n: int, perturbed: bool = False):
        compiled.wait_for_background()  # see envs.contract.make_runtime
        self.plant = plant
        self.system = s = plant.system
        self.n = n
        self.control_period = plant.control_period
        self.substeps = plant.substeps
        self.integrator = plant.integrator
        self.num_threads = plant.num_threads
        widths = (s.state_size, s.state_size, s.n_u, None, len(plant.goal_names),
                  len(plant.actuated), plant.obs_size, len(plant.task.terms), None,
                  len(plant.row_names), len(s.output_names), None, 2, s.n_c)  # fmt: skip
        # every per-row array is a view of one of three flat buffers (float64, bool, and
        # the step counts), so that the fused step takes them in a few arguments
        self._floats = tuple(zip(self._FLOATS, widths))
        self._bools = self._BOOLS
        width = sum(1 if w is None else w for w in widths)
        self._F = np.zeros(n * width)
        self._B = np.zeros(n * len(self._bools), dtype=np.bool_)
        self.steps = np.zeros(n, dtype=np.int64)
        self.O = np.zeros((n, plant.obs_size), dtype=np.float32)
        spec = plant.perturb if perturbed else None
        self._pushed = spec is not None and spec.push is not None
        # the parameters of every row (pushes integrate with one row of them per copy)
        self.parameters = ParameterRows(plant, n, rows=self._pushed)
        self._redraws = plant.randomize is not None and bool(plant.randomize.intervals)
        # the plant's perturbations (envs.perturb), applied only by the env's own runtime
        self.perturber = None if spec is None else Perturber(spec, plant, n)
        self._views()
        self._compile()
        if self.parameters.randomized and len(plant.context):  # the env's values, observed
            self._observe_context(slice(None))

    @property
    def per_row(self) -> bool:
        """Whether the copies may step with parameters of their own (`randomize=`)."""
        return self.parameters.randomized

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

    def _compile(self) -> None:
        plant, store = self.plant, self.parameters
        self._model_params = store.model_params  # what the model's kernels read
        self._task_params = store.task_params  # what the task's functions read as p
        jitted = compiled.compile_functions(self)
        self._lowest = float(plant.lowest_reward)
        self._term_names = [t.name for t in plant.task.terms]
        # the kernels on the runtime's own arrays (bound after a call on copies, which
        # compiles or loads them for exactly these types)
        warm = compiled.warm
        self._observe = warm(observe, self._rows_x, self.G, plant.ops, plant.obs_low,
                             plant.obs_high, self._obs64)  # fmt: skip
        self._advance = warm(advance, self.X, self._X_next, plant.limits, self.diverged,
                             self.T, 0.0, self.steps, -1, self._steps_left)  # fmt: skip
        self._finish = warm(finish, self.terms, plant.term_low, plant.term_high, self._failed,
                            self.diverged, self._steps_left, self._lowest, self.R,
                            self.terminated, self.success, self._obs64, plant.obs_low,
                            self.O)  # fmt: skip
        # the kernels take the shared vector p and, where copies differ, their rows P (None:
        # every copy has p; numba prunes that branch, so each form compiles only its own)
        self._p_shared, self._P = store.nominal, store.P
        module = self.system.kernel_module
        # the model's kernels' addresses, for the energy and the constraints' residual in info
        kernels = ("energy_terms", "residual") if module.N_C else ("energy_terms",)
        self._table = stepping.table(module, *kernels)
        # one kernel for both (`dynamics.rows.state_batch`), bound for these arrays, and
        # the arguments of each (the arrays are the buffers' views, never swapped)
        self._energy_args = (self.T, self.X, self._p_shared, self._P, self._E, self._table,
                             stepping.AT_ENERGY)  # fmt: skip
        self._residual_args = (*self._energy_args[:4], self._C, self._table,
                               stepping.AT_RESIDUAL)  # fmt: skip
        self._of_state = warm(state_batch, *self._energy_args)
        # fewer rows than the model's vector lanes take step one at a time (`erk_row`, as
        # its `erk_rows` would: the same operations), in the fused step and without it
        self._row_by_row = self.n < stepping.LANES_FROM and not self._pushed
        self._tableau = method_tableau(self.integrator)
        self._fused_pending = None  # the thread compiling the fused step, if one does
        self._separate_steps = 0  # steps taken by separate calls while it was not bound
        compiled.compile_fused(self, jitted)
        # until the fused step is bound (which compiles the vector-lane kernels), up to
        # ONE_BY_ONE rows step one at a time too, as the lanes would (`erk_row`), when numba's
        # cache has no lanes yet: a vector env stepped a few times never compiles them
        derivative = getattr(module, stepping.lane_kernels(self.parameters.per_row, False)[0])
        lanes = _kernel_compiled(stepping.erk_rows) and _kernel_compiled(derivative)
        self._one_by_one = (self._fused is not None and not self._pushed
                            and self.n <= ONE_BY_ONE and not lanes)  # fmt: skip

    # pickling: numba dispatchers are rebuilt (from numba's cache) rather than pickled
    def __getstate__(self):
        state = self.__dict__.copy()
        for k in ("_reward", "_success", "_failure", "_derived", "_observe", "_advance",
                  "_finish", "_fused", "_fused_bound", "_fused_C", "_fused_K", "_calls",
                  "_of_state", "_types", "_E0", "_model_params", "_task_params", "_p_shared",
                  "_P", "_table", "_energy_args", "_residual_args", "_fused_pending"):  # fmt: skip
            state.pop(k, None)
        for name in (*(f for f, _ in self._floats), *self._bools):  # views of the buffers
            state.pop(name)
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._views()
        self._compile()

    # ---- parameters (envs.parameters) ----------------------------------------------------
    def set_params(self, rows, values: np.ndarray, pins=None) -> None:
        """Rows `rows` step from now on with parameters `values` (len(rows), n_p), columns
        in the order of `system.parameters` (checked by the caller): a masked write into
        the store, nothing recompiled; the observed parameters follow."""
        self.parameters.write(rows, values, pins)
        self._observe_context(rows)

    def _observe_context(self, rows) -> None:
        """The observed parameters' columns of `rows` (clipped into their bounds)."""
        plant, P = self.plant, self.parameters.P
        for col, j in plant.context.tolist():
            lo, hi = plant.obs_low[col], plant.obs_high[col]
            self._obs64[rows, col] = np.clip(P[rows, j], lo, hi)
            self.O[rows, col] = self._obs64[rows, col]

    def params(self, row: int | None = None) -> dict:
        """The parameter values in force: name -> float of one row, or (N,) read-only
        arrays (kept until the next write: a step's info costs no copies)."""
        return self.parameters.values(row)

    # ---- episodes --------------------------------------------------------------------------
    def start(self, rngs, options: dict | None, rows: list[int], batch: int | None,
              seeded: bool = False):  # fmt: skip
        """(states, goals, (parameters, pins) or None) that `rows` start an episode with,
        changing nothing: the parameters first (`ParameterRows.draw`, from each row's
        generator `rngs[i]`; once-only draws again where `seeded`), then the starting
        states and goals (`Plant.start_rows`, projected with the rows' parameters)."""
        drawn = self.parameters.draw(rngs, options, rows, batch, seeded)
        params = None if drawn is None else drawn[0]
        x, g = self.plant.start_rows(rngs, options, rows, batch, params)
        return x, g, drawn

    def begin(self, rows: list[int], x, g, drawn, rngs=None) -> None:
        """Put `rows` at the start `start` gave (their parameters, then their states); a
        perturbed runtime's rows draw their perturbations from generators spawned from
        their reset generators `rngs` (indexed by row)."""
        if drawn is not None:
            self.set_params(rows, *drawn)
        if self.perturber is not None and rngs is not None:
            self.perturber.reseed(rows, [rngs[i] for i in rows])
        self.reset_rows(rows, x, g)

    def redraw(self, rngs, mask=None) -> None:
        """After a step: the mid-episode redraws (`when=k`) due in the copies (where
        `mask`), from their generators `rngs`."""
        if self._redraws:
            rows = self.parameters.redraw_due(rngs, self.steps, mask)
            if rows:
                self._observe_context(rows)

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
        self.terms[rows] = 0.0
        self.R[rows] = 0.0
        plant = self.plant
        x, g, a = self.rows()[rows], self.G[rows], self.A[rows]
        obs = self._obs64[rows]  # a copy: every column is rewritten but the context's
        observe(x, g, plant.ops, plant.obs_low, plant.obs_high, obs)
        for col, fn in self._derived:
            obs[:, col] = fn(x, a, g, self.parameters.task_rows(rows))
        np.clip(obs, plant.obs_low, plant.obs_high, out=obs)
        self._obs64[rows] = obs
        self.O[rows] = obs
        if self.perturber is not None:
            index = np.arange(self.n)[rows]
            self.perturber.clear(index)
            self.perturber.observe(self._obs64, self.O, index)

    # ---- the step --------------------------------------------------------------------------
    def step(self, actions: np.ndarray, horizon: int | None) -> bool:
        """Advance every row one control period under `actions` (N, n_a), finite; the
        early-end penalty counts the steps left to `horizon` (None: no time limit, no
        penalty). Returns whether any row diverged."""
        plant = self.plant
        if actions.dtype != np.float64:  # one type for the compiled step (`compiled.actions_type`);
            actions = actions.astype(np.float64)  # float32's values exactly
        perturbed = ()
        if self.perturber is not None:  # the inputs applied and the pushes (envs.perturb)
            if not np.isfinite(actions).all():
                raise NonFiniteActions("actions contain NaN or inf")
            perturbed = self.perturber.before_step(actions, self.T, self.X, self._model_params)
        step = None if self._fused is None else self._fused_step()
        if step is not None:
            code = step(actions, self._F, self._B, self.steps, self.O, self._fused_C,
                        self._fused_K, self._model_params, self._task_params,
                        -1 if horizon is None else horizon, *perturbed)  # fmt: skip
            if code < 0:
                raise NonFiniteActions("actions contain NaN or inf")
            if perturbed:
                self.perturber.observe(self._obs64, self.O)
            return code > 0
        if not apply_actions(actions, plant.input_mid, plant.input_half, plant.actuated, self.A,
                             self.U):  # fmt: skip
            raise NonFiniteActions("actions contain NaN or inf")
        if perturbed:
            self.U[:, plant.actuated] = perturbed[0]
        self._integrate(perturbed)
        diverged = self._advance(self.X, self._X_next, plant.limits, self.diverged, self.T,
                                 self.control_period, self.steps,
                                 -1 if horizon is None else horizon, self._steps_left)  # fmt: skip
        bad = self._evaluate(self._steps_left)
        if perturbed:
            self.perturber.observe(self._obs64, self.O)
        return bool(diverged) or bool(bad)

    def _fused_step(self):
        """The fused step's machine code, or None while it compiles in the background
        (`envs.compiled.fused_for`)."""
        step = self._fused_bound
        return compiled.fused_for(self) if step is None else step

    def _integrate(self, perturbed) -> None:
        """The step of separate calls: X_next from X under U, with the pushes' forces."""
        s, args = self.system, (self.control_period, self.substeps, self._X_next, self.integrator)
        if self._row_by_row or (self._one_by_one and self._fused_bound is None):
            P, per_row = self._model_params, self.parameters.per_row
            h = self.control_period / self.substeps
            model = stepping.table(s.kernel_module, "derivative_lanes")
            for r in range(self.n):  # stepping.erk_row advances row r into _X_next
                stepping.erk_row(self.T, self.X, self.U, P[r] if per_row else P, h,
                                 self.substeps, *self._tableau, self._X_next, r, model)  # fmt: skip
        elif self._pushed:
            s.step_pushed_unchecked(self.T, self.X, self.U, self._model_params, perturbed[1], *args)
        elif self.parameters.per_row:
            s.step_rows_unchecked(self.T, self.X, self.U, self._model_params, *args,
                                  self.num_threads)  # fmt: skip
        else:
            s.step_unchecked(self.T, self.X, self.U, *args, self.num_threads)

    def _evaluate(self, steps_left: np.ndarray) -> bool:
        plant, p = self.plant, self._task_params
        x = self.rows()
        self._observe(x, self.G, plant.ops, plant.obs_low, plant.obs_high, self._obs64)
        if self._derived:  # the declared features are clipped by `observe` already
            for col, fn in self._derived:
                self._obs64[:, col] = fn(x, self.A, self.G, p)
            np.clip(self._obs64, plant.obs_low, plant.obs_high, out=self._obs64)
        for k, v in enumerate(self._reward(x, self.A, self.G, p)):
            self.terms[:, k] = v
        self.success[:] = self._success(x, self.A, self.G, p)
        if self._failure is not None:
            self._failed[:] = self._failure(x, self.A, self.G, p)
        return self._finish(self.terms, plant.term_low, plant.term_high, self._failed,
                            self.diverged, steps_left, self._lowest, self.R,
                            self.terminated, self.success, self._obs64, plant.obs_low,
                            self.O)  # fmt: skip

    def rows(self) -> np.ndarray:
        """The rows the task functions see: the state, then the declared model outputs."""
        plant = self.plant
        if not len(plant.output_index):
            return self.X
        model = stepping.table(self.system.kernel_module, "accelerations", "outputs")
        # every row's own parameters, or (P None) the shared ones
        outputs_batch(self.T, self.X, self.U, self._p_shared, self._P, self._Y, model)
        n_x = self.system.state_size
        self._rows_x[:, :n_x] = self.X
        self._rows_x[:, n_x:] = self._Y[:, plant.output_index]
        return self._rows_x

    # ---- diagnostics ---------------------------------------------------------------------
    def energy(self) -> np.ndarray:
        """T + V of every row, J."""
        self._of_state(*self._energy_args)
        return self._E.sum(axis=1)

    def energy_of_row0(self) -> float:
        """T + V of the first row, J (the single env's cheap path)."""
        self._of_state(*self._energy_args)
        kinetic, potential = self._E0.tolist()
        return kinetic + potential

    def constraint_residual(self) -> np.ndarray:
        """The velocity-constraint residual of every row (N, n_c)."""
        if self.system.n_c:
            self._of_state(*self._residual_args)
        return self._C.copy()

    def reward_terms(self, row: int | None = None):
        """The clipped reward terms, by name: floats of one row, or arrays of every row."""
        names = self._term_names
        if row is None:
            return {k: self.terms[:, i].copy() for i, k in enumerate(names)}
        return dict(zip(names, self.terms[row].tolist()))


__all__ = ["NonFiniteActions", "Runtime"]
