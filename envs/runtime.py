"""The batched runtime: N rows of one task on one compiled system.

`Runtime` owns the state, goal, input and result arrays of N copies and their
parameter store (`envs.parameters.ParameterRows`), and offers the operations that write
them: `start` (what rows start an episode with, changing nothing), `begin` (put rows
there: their parameters, then `reset_rows`), `step` (every row by one control period) and
`redraw` (the mid-episode parameter redraws due). The single env is a runtime of one row
and the native vector env one of N rows, each a thin Gymnasium wrapper; nothing else
writes these arrays (docs/architecture.md names the writer of each).

The step is one object, `envs.step.Step`, built here from the plant, the rows' arrays
(`envs.arrays.RowArrays`) and the perturber: per step, clip and scale the actions, the
task's integrator (RK4 or DOP853 substeps) through the compiled system, check every row
for divergence, then evaluate the task on the post-step state (observation, reward terms,
success and failure). A row that fails or diverges terminates, and its reward carries the
early-end penalty of `envs.task.Task`. The runtime hands the step the store's
`model_params` (what the model's kernels read) and `task_params` (what the task's
functions read as p) at every call; nothing reaches back for a parameter.

The env's own runtime (`perturbed=True`) applies the plant's perturbations (`envs.perturb`):
before a step, the inputs applied and the pushes' generalised forces replace the commanded
inputs (a variant of the fused step takes them); after it, the observation handed out gets
its noise. Other runtimes of the plant (`env.simulator(n)`) step the nominal plant.
"""

from __future__ import annotations

import numpy as np

from dynamics import stepping
from dynamics.rows import state_batch

from .arrays import RowArrays
from .compiled import warm
from .observation import observe
from .parameters import ParameterRows
from .perturb import Perturber
from .plant import Plant
from .step import NonFiniteActions, Step, wait_for_background

ARRAYS = ("X", "U", "T", "G", "A", "O", "terms", "R", "steps", "terminated", "success", "diverged")
"""The arrays of `RowArrays` the runtime shows wrappers as its own attributes (the same
views, never rebound)."""


class Runtime:
    """N rows of a task (see the module docstring). Public arrays are views for wrappers to
    read; the runtime's own methods and its step are their only writers."""

    def __init__(self, plant: Plant, n: int, perturbed: bool = False):
        wait_for_background()  # see envs.contract.make_runtime
        self.plant = plant
        self.system = s = plant.system
        self.n = n
        self.control_period = plant.control_period
        self.substeps = plant.substeps
        self.integrator = plant.integrator
        self.num_threads = plant.num_threads
        widths = (
            s.state_size,
            s.state_size,
            s.n_u,
            None,
            len(plant.goal_names),
            len(plant.actuated),
            plant.obs_size,
            len(plant.task.terms),
            None,
            len(plant.row_names),
            len(s.output_names),
            None,
            2,
            s.n_c,
        )
        # every per-row array is a view of one of a few flat buffers (envs.arrays), so that
        # the fused step takes them in a few arguments
        self.arrays = RowArrays(n, widths, plant.obs_size)
        spec = plant.perturb if perturbed else None
        self._pushed = spec is not None and spec.push is not None
        # the parameters of every row (pushes integrate with one row of them per copy)
        self.parameters = ParameterRows(plant, n, rows=self._pushed)
        self._redraws = plant.randomize is not None and bool(plant.randomize.intervals)
        # the plant's perturbations (envs.perturb), applied only by the env's own runtime
        self.perturber = None if spec is None else Perturber(spec, plant, n)
        self._build()
        if self.parameters.randomized and len(plant.context):  # the env's values, observed
            self._observe_context(slice(None))

    @property
    def per_row(self) -> bool:
        """Whether the copies may step with parameters of their own (`randomize=`)."""
        return self.parameters.randomized

    def _build(self) -> None:
        """The step and the diagnostics' kernel on the arrays (again after unpickling)."""
        for name in ARRAYS:
            setattr(self, name, getattr(self.arrays, name))
        self.stepper = Step(self.plant, self.arrays, self.parameters, self.perturber, self._pushed)
        self._term_names = [t.name for t in self.plant.task.terms]
        module = self.system.kernel_module
        # the model's kernels' addresses, for the energy and the constraints' residual in
        # info: one kernel for both (`dynamics.rows.state_batch`), bound for these arrays
        kernels = ("energy_terms", "residual") if module.N_C else ("energy_terms",)
        self._table = stepping.table(module, *kernels)
        self._of_state = warm(state_batch, *self._state_args(self.arrays.E, stepping.AT_ENERGY))

    def _state_args(self, out, kernel) -> tuple:
        a, store = self.arrays, self.parameters  # the shared vector, and every row's or None
        return a.T, a.X, store.nominal, store.P, out, self._table, kernel

    # pickling: the step's numba dispatchers are rebuilt (from numba's cache), not pickled
    def __getstate__(self):
        state = self.__dict__.copy()
        for k in ("stepper", "_of_state", "_table", *ARRAYS):
            state.pop(k, None)
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._build()

    # ---- parameters (envs.parameters) ----------------------------------------------------
    def set_params(self, rows, values: np.ndarray, pins=None) -> None:
        """Rows `rows` step from now on with parameters `values` (len(rows), n_p), columns
        in the order of `system.parameters` (checked by the caller): a masked write into
        the store, nothing recompiled; the observed parameters follow."""
        self.parameters.write(rows, values, pins)
        self._observe_context(rows)

    def _observe_context(self, rows) -> None:
        """The observed parameters' columns of `rows` (clipped into their bounds)."""
        plant, P, obs64 = self.plant, self.parameters.P, self.arrays.obs64
        for col, j in plant.context.tolist():
            lo, hi = plant.obs_low[col], plant.obs_high[col]
            obs64[rows, col] = np.clip(P[rows, j], lo, hi)
            self.O[rows, col] = obs64[rows, col]

    def params(self, row: int | None = None) -> dict:
        """The parameter values in force: name -> float of one row, or (N,) read-only
        arrays (kept until the next write: a step's info costs no copies)."""
        return self.parameters.values(row)

    # ---- episodes --------------------------------------------------------------------------
    def start(
        self, rngs, options: dict | None, rows: list[int], batch: int | None, seeded: bool = False
    ):
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
        plant, obs64 = self.plant, self.arrays.obs64
        x, g, a = self.rows()[rows], self.G[rows], self.A[rows]
        obs = obs64[rows]  # a copy: every column is rewritten but the context's
        observe(x, g, plant.ops, plant.obs_low, plant.obs_high, obs)
        for col, fn in self.stepper.derived:
            obs[:, col] = fn(x, a, g, self.parameters.task_rows(rows))
        np.clip(obs, plant.obs_low, plant.obs_high, out=obs)
        obs64[rows] = obs
        self.O[rows] = obs
        if self.perturber is not None:
            index = np.arange(self.n)[rows]
            self.perturber.clear(index)
            self.perturber.observe(obs64, self.O, index)

    # ---- the step --------------------------------------------------------------------------
    def step(self, actions: np.ndarray, horizon: int | None) -> bool:
        """Advance every row one control period under `actions` (N, n_a), finite; the
        early-end penalty counts the steps left to `horizon` (None: no time limit, no
        penalty). Returns whether any row diverged."""
        if actions.dtype != np.float64:  # one type for the compiled step (`compiled.actions_type`);
            actions = actions.astype(np.float64)  # float32's values exactly
        store, perturbed = self.parameters, ()
        model_params = store.model_params
        if self.perturber is not None:  # the inputs applied and the pushes (envs.perturb)
            if not np.isfinite(actions).all():
                raise NonFiniteActions("actions contain NaN or inf")
            perturbed = self.perturber.before_step(actions, self.T, self.X, model_params)
        diverged = self.stepper.step(
            actions, model_params, store.task_params, -1 if horizon is None else horizon, perturbed
        )
        if perturbed:
            self.perturber.observe(self.arrays.obs64, self.O)
        return diverged

    def rows(self) -> np.ndarray:
        """The rows the task functions see: the state, then the declared model outputs."""
        return self.stepper.rows(self.parameters.model_params)

    # ---- diagnostics ---------------------------------------------------------------------
    def energy(self) -> np.ndarray:
        """T + V of every row, J."""
        self._of_state(*self._state_args(self.arrays.E, stepping.AT_ENERGY))
        return self.arrays.E.sum(axis=1)

    def energy_of_row0(self) -> float:
        """T + V of the first row, J (the single env's cheap path)."""
        a, store = self.arrays, self.parameters
        self._of_state(a.T, a.X, store.nominal, store.P, a.E, self._table, stepping.AT_ENERGY)
        kinetic, potential = a.E0.tolist()
        return kinetic + potential

    def constraint_residual(self) -> np.ndarray:
        """The velocity-constraint residual of every row (N, n_c)."""
        if self.system.n_c:
            self._of_state(*self._state_args(self.arrays.C, stepping.AT_RESIDUAL))
        return self.arrays.C.copy()

    def reward_terms(self, row: int | None = None):
        """The clipped reward terms, by name: floats of one row, or arrays of every row."""
        names = self._term_names
        if row is None:
            return {k: self.terms[:, i].copy() for i, k in enumerate(names)}
        return dict(zip(names, self.terms[row].tolist()))


__all__ = ["NonFiniteActions", "Runtime"]
