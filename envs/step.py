"""A runtime's step: every row by one control period, through one of two routes.

`Step` is built by the runtime from the plant, its arrays (`envs.arrays.RowArrays`) and
the perturber, and owns everything the step runs: the task's functions compiled
(`envs.compiled`), the kernels bound to the arrays, the fused step (`envs.fused`) and its
compile in the background, and the step of separate calls. It offers one call,
`step(actions, model_params, task_params, horizon, perturbed)`: the store's arrays are
its arguments, never kept. Per step it takes one of two routes, with the same results bit
for bit: the fused step, one compiled call, when every task function compiles and one
thread steps the rows; else separate calls: the actions applied, `System.step_unchecked`
(the model's one unchecked step) and the task evaluated.

A new task's fused step compiles in a thread after the first `SEPARATE_FIRST` steps,
which separate calls take. The thread hands its result back through one `Future`; the
stepping thread alone installs it (`_take`).
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import Future

import numpy as np

from dynamics import calls, stepping
from dynamics.cache import compiled as kernel_compiled
from dynamics.rows import outputs_batch
from dynamics.system import BLOCK, method_tableau

from . import fused, names
from .arrays import BOOLS
from .compiled import actions_type, as_fused, compile_functions, pack, warm
from .observation import observe
from .row_kernels import advance, apply_actions, finish

ONE_BY_ONE = 64
"""Rows a vector env steps one at a time before its fused step is bound (see `Step`):
for at most 2,000 steps (`SEPARATE_FIRST`), about 6 us a row more than the lanes
(the arm: 521 against 146 us a step at 64 rows, so at most 0.8 s over those steps), against
compiling in the main thread what the lanes need and `erk_row` does not: the integrator's
lanes (once per machine, 1.5-2 s of CPU) and, for rows with their own parameters, the
model's `derivative_lanes_p` (0.3-1.3 s); the fused step's thread compiles them."""

SEPARATE_FIRST = 2_000
"""Steps a runtime takes by separate calls before its new fused step starts compiling: an
env stepped for an episode or a few (a check, a test, a look at a model) never compiles
it. The separate calls cost about 35 us a step more than the fused step (the arm and the
cart-pole here: 54 and 46 us against 17 and 13), so 0.07 s over these steps, against 2-3 s
of CPU to compile the step; a longer run compiles it once, for numba's cache."""


class NonFiniteActions(ValueError):
    """`Runtime.step` was given a NaN or inf action (nothing was changed)."""


class Step:
    """The step of a runtime's rows (see the module docstring). `plant`: the bound plant;
    `arrays`: the rows' arrays; `store`: the parameter store, read once here for the
    sample the functions compile with; `perturber`: the plant's perturbations or None;
    `pushed`: whether pushes add forces (the integration takes them)."""

    def __init__(self, plant, arrays, store, perturber, pushed: bool):
        self.plant, self.arrays, self.perturber, self.pushed = plant, arrays, perturber, pushed
        self.system = s = plant.system
        self.n = n = arrays.n
        self.per_row = store.per_row
        a = arrays
        self.types, functions, self.jitted = compile_functions(plant, a, store.task_params)
        self.reward, self.success = functions["reward"], functions["success"]
        self.failure, self.derived = functions["failure"], functions["derived"]
        self.lowest = float(plant.lowest_reward)
        # the kernels on the rows' own arrays (bound after a call on copies, which
        # compiles or loads them for exactly these types)
        self._observe = warm(
            observe, a.rows_x, a.G, plant.ops, plant.obs_low, plant.obs_high, a.obs64
        )
        self._advance = warm(
            advance, a.X, a.X_next, plant.limits, a.diverged, a.T, 0.0, a.steps, -1, a.steps_left
        )
        # the end of a step's arguments: the rows' buffers and the plant's bounds, fixed
        self._finish_args = (
            a.terms,
            plant.term_low,
            plant.term_high,
            a.failed,
            a.diverged,
            a.steps_left,
            self.lowest,
            a.R,
            a.terminated,
            a.success,
            a.obs64,
            plant.obs_low,
            a.O,
        )
        self._finish = warm(finish, *self._finish_args)
        # fewer rows than the model's vector lanes step one at a time (`erk_row`, as
        # `erk_rows` would: the same operations), in the fused step and without it
        self.row_by_row = n < stepping.LANES_FROM and not pushed
        self.tableau = method_tableau(plant.integrator)
        self.fused = self._build_fused(store)
        self.bound = None  # the fused step's machine code, once bound
        self._compiling: Future | None = None  # the fused step compiling in a thread
        self._separate_steps = 0  # steps taken by separate calls while it was not bound
        # until the fused step is bound (which compiles the vector-lane kernels), up to
        # ONE_BY_ONE rows step one at a time too, as the lanes would (`erk_row`), when
        # numba's cache has no lanes yet: a vector env stepped a few times never compiles them
        derivative = getattr(s.kernel_module, stepping.lane_kernels(self.per_row, False)[0])
        lanes = kernel_compiled(stepping.erk_rows) and kernel_compiled(derivative)
        self.one_by_one = self.fused is not None and not pushed and n <= ONE_BY_ONE and not lanes

    # ---- the one call ----------------------------------------------------------------------
    def step(self, actions, model_params, task_params, horizon, perturbed=()) -> bool:
        """Every row by one control period under `actions` (N, n_a) float64, with the
        store's `model_params` and `task_params`; `horizon`: steps to the time limit (-1:
        none); `perturbed`: the perturber's (inputs applied, pushes' forces), or ().
        Returns whether any row diverged; NonFiniteActions for a NaN or inf action."""
        fused_step = self.bound
        if fused_step is None and self.fused is not None:
            fused_step = self._take(model_params, task_params)
        a = self.arrays
        if fused_step is not None:
            code = fused_step(
                actions,
                a.F,
                a.B,
                a.steps,
                a.O,
                self.C,
                self.K,
                model_params,
                task_params,
                horizon,
                *perturbed,
            )
            if code < 0:
                raise NonFiniteActions("actions contain NaN or inf")
            return code > 0
        plant = self.plant
        if not apply_actions(actions, plant.input_mid, plant.input_half, plant.actuated, a.A, a.U):
            raise NonFiniteActions("actions contain NaN or inf")
        if perturbed:
            a.U[:, plant.actuated] = perturbed[0]
        alone = ONE_BY_ONE + 1 if self.one_by_one and self.bound is None else stepping.LANES_FROM
        self.system.step_unchecked(
            a.T,
            a.X,
            a.U,
            plant.control_period,
            plant.substeps,
            a.X_next,
            plant.integrator,
            plant.num_threads,
            P=model_params,
            W=perturbed[1] if perturbed else None,
            alone_below=alone,
        )
        diverged = self._advance(
            a.X,
            a.X_next,
            plant.limits,
            a.diverged,
            a.T,
            plant.control_period,
            a.steps,
            horizon,
            a.steps_left,
        )
        bad = self.evaluate(model_params, task_params)
        return bool(diverged) or bool(bad)

    def evaluate(self, shared, task_params) -> bool:
        """The task on the post-step state: observation, reward terms, success, failure
        and the rows that end (the early-end penalty counts `steps_left`)."""
        plant, a, p = self.plant, self.arrays, task_params
        x = self.rows(shared)
        self._observe(x, a.G, plant.ops, plant.obs_low, plant.obs_high, a.obs64)
        if self.derived:  # the declared features are clipped by `observe` already
            for col, fn in self.derived:
                a.obs64[:, col] = fn(x, a.A, a.G, p)
            np.clip(a.obs64, plant.obs_low, plant.obs_high, out=a.obs64)
        for k, v in enumerate(self.reward(x, a.A, a.G, p)):
            a.terms[:, k] = v
        a.success[:] = self.success(x, a.A, a.G, p)
        if self.failure is not None:
            a.failed[:] = self.failure(x, a.A, a.G, p)
        return self._finish(*self._finish_args)

    def rows(self, model_params) -> np.ndarray:
        """The rows the task functions see: the state, then the declared model outputs
        (with `model_params`: the shared vector or every row's own)."""
        plant, a = self.plant, self.arrays
        if not len(plant.output_index):
            return a.X
        model = stepping.table(self.system.kernel_module, "accelerations", "outputs")
        outputs_batch(a.T, a.X, a.U, *shared_and_rows(model_params), a.Y, model)
        n_x = self.system.state_size
        a.rows_x[:, :n_x] = a.X
        a.rows_x[:, n_x:] = a.Y[:, plant.output_index]
        return a.rows_x

    def separate(self, one_by_one: bool | None = None) -> None:
        """Take the step of separate calls from now on (tests compare the routes);
        `one_by_one`: whether up to ONE_BY_ONE rows step one at a time (None: as they do)."""
        self.fused = None
        if one_by_one is not None:
            self.one_by_one = one_by_one

    # ---- the fused step ----------------------------------------------------------------------
    def _build_fused(self, store):
        """The fused step (envs.fused), when every task function is compiled and one
        thread steps the rows; else None (the step of separate calls)."""
        plant = self.plant
        if plant.num_threads > 1 and self.n > BLOCK:
            return None
        if not all(hasattr(f, "py_func") for f in self.jitted.values()):
            return None
        functions = {"_apply": apply_actions, "_advance": advance}
        if len(plant.output_index):
            functions["_outputs"] = outputs_batch
        functions.update(_observe=observe, **self.jitted, _finish=finish)
        plan, self.C, self.K = self._plan(functions, store)
        return fused.build(plan, functions, dict(zip(("_Rows", "_Actions", "_Goal"), self.types)))

    def _plan(self, functions: dict, store):
        """(plan, constants as float64, constants as int64) of the fused step, which calls
        `functions` (role -> kernel) and the model's integrator through their addresses:
        `calls` lists (slot in the int64 constants, kernel, argument types) for `bind`."""
        plant, s = self.plant, self.system
        ta, tw, tc = self.tableau
        floats = list(self.arrays.segments())
        bools = [(name, k) for k, name in enumerate(BOOLS)]
        h = plant.control_period / plant.substeps
        real = [
            ("input_mid", plant.input_mid),
            ("input_half", plant.input_half),
            ("limits", plant.limits),
            ("obs_low", plant.obs_low),
            ("obs_high", plant.obs_high),
            ("term_low", plant.term_low),
            ("term_high", plant.term_high),
            ("ta", ta),
            ("tw", tw),
            ("tc", tc),
            ("h", h),
            ("dt", plant.control_period),
            ("lowest", self.lowest),
        ]
        roles = ["integrator", *functions]
        whole = [
            ("actuated", plant.actuated),
            ("ops", plant.ops),
            ("output_index", plant.output_index),
            ("substeps", plant.substeps),
            ("block", BLOCK),
            ("addresses", np.zeros(len(roles))),
            ("model_kernels", np.zeros(stepping.TABLE_SIZE)),
        ]
        # addresses: of the kernels the step calls; model_kernels: the model's table, which
        # the integrator reads (dynamics.stepping); both written by `_install` (dynamics.calls)
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
            "types": [cls.__name__ for cls in self.types],
            "perturbed": self.perturber is not None,
            "pushed": self.pushed,
            "rows": self.per_row,  # each row's own parameters
            "row_by_row": self.row_by_row,  # erk_row, one row at a time; else erk_rows
        }
        at = next(start for name, start, *_ in whole_constants if name == "addresses")
        self.table_slot = next(
            start for name, start, *_ in whole_constants if name == "model_kernels"
        )
        kinds = self._variable_types(plan, store)
        self.calls = [(at, *self._integrator(kinds))]
        for role in functions:
            self.calls.append(
                (
                    at + len(self.calls),
                    functions[role],
                    tuple(kinds[v] for v in fused.arguments(role)),
                )
            )
        plan["calls"] = {
            role: (slot - at, calls.label(kernel, types))
            for role, (slot, kernel, types) in zip(roles, self.calls)
        }
        return plan, C, K

    def _variable_types(self, plan: dict, store) -> dict:
        """The numba type of each variable of the generated step that a kernel takes: the
        rows' arrays as views of the flat buffers (contiguous), the constants, the step's
        arguments and the named inputs (envs.fused.source)."""
        from numba import typeof
        from numba.core import types

        f8, i8, a = types.float64, types.int64, self.arrays
        kinds = {
            "actions": actions_type(),
            "steps": typeof(a.steps),
            "O": typeof(a.O),
            "model_params": typeof(store.model_params),
            "task_params": typeof(store.task_params),
            "horizon": i8,
        }
        for name, _, width in plan["floats"]:
            kinds[fused.RENAMED.get(name, name)] = types.Array(f8, 1 if width is None else 2, "C")
        for name, _ in plan["bools"]:
            kinds[name] = types.Array(types.boolean, 1, "C")
        for name, _, _, shape in plan["constants"]:
            dtype = i8 if name in plan["integer_constants"] else f8
            kinds[name] = dtype if shape is None else types.Array(dtype, len(shape), "C")
        if self.perturber is not None:  # the inputs applied and the pushes' forces
            kinds.update(applied=typeof(self.perturber.applied), W=typeof(self.perturber.W))
        params = kinds["model_params"]
        one = params.copy(ndim=1) if plan["rows"] else params  # a row's, or all rows
        kinds.update(one_params=one, row_params=params if plan["rows"] else types.none)
        kinds["x"] = kinds["rows_x" if plan["outputs"] else "X"]
        for var, cls in zip(("xs", "as_", "gs"), self.types):  # columns of x, A and G by name
            kinds[var] = as_fused(typeof(names.columns(cls, np.zeros((1, len(cls._fields))))))
        return kinds

    def _integrator(self, kinds: dict):
        """(kernel, argument types) of the integrator as the fused step calls it (`kinds`:
        `_variable_types`): `erk_row` one row at a time, or `erk_rows` a block at a time
        (see envs.fused), both of `dynamics.stepping`, with the model's table last."""
        from numba.core import types

        i8, table = types.int64, kinds["model_kernels"]
        head = tuple(kinds[v] for v in ("T", "X", "U", "one_params"))
        tableau = tuple(kinds[v] for v in ("h", "substeps", "ta", "tw", "tc", "X_next"))
        if self.row_by_row:
            return stepping.erk_row, (*head, *tableau, i8, table)
        forces = kinds["W"] if self.pushed else types.none
        return stepping.erk_rows, (*head, kinds["row_params"], forces, *tableau, i8, i8, table)

    def _table_names(self) -> tuple[str, ...]:
        """The model's kernels the fused step calls through the integrator and
        `outputs_batch` (`dynamics.stepping.table`)."""
        if self.row_by_row:
            lanes = ("derivative_lanes",)
        else:
            lanes = stepping.lane_kernels(self.per_row, self.pushed)
        return (*lanes, "accelerations", "outputs") if len(self.plant.output_index) else lanes

    def _compile(self, model_params, task_params):
        """(the model's table, the kernels' addresses, the step's machine code): the fused
        step and every kernel it calls compiled (or loaded from numba's cache) for float64
        actions of any layout (`actions_type`). Writes nothing: `_install` does."""
        table = stepping.table(self.system.kernel_module, *self._table_names())
        addresses = [calls.address(kernel, types) for _, kernel, types in self.calls]
        a = self.arrays
        args = (a.F, a.B, a.steps, a.O, self.C, self.K, model_params, task_params, -1)
        if self.perturber is not None:  # samples of the applied inputs and the forces
            args += (self.perturber.applied, self.perturber.W)
        signature = (actions_type(), *(self.fused.typeof_pyval(x) for x in args))
        self.fused.compile(signature)
        return table, addresses, self.fused.overloads[signature].entry_point

    def _install(self, compiled) -> None:
        table, addresses, entry = compiled
        at = self.table_slot  # first the model's kernels, which the integrator calls
        self.K[at : at + len(table)] = table
        for (slot, *_), address in zip(self.calls, addresses):
            self.K[slot] = address
        self.bound = entry

    def bind(self, model_params, task_params):
        """The fused step's machine code, compiled (or loaded) and bound now."""
        self._install(self._compile(model_params, task_params))
        return self.bound

    def _take(self, model_params, task_params):
        """The fused step, bound, or None while the step of separate calls runs: when
        numba's cache does not have the step, the first `SEPARATE_FIRST` steps are separate
        calls, and then the step compiles in a thread of its own while separate calls go
        on; the thread's result (or error, raised here) comes back through its `Future`.
        Both routes give the same results bit for bit, and by then the separate calls have
        run (so compiled) every kernel they use: a first call of a kernel while the thread
        compiles would wait for numba's compiler lock, that is for the whole step. So a new
        model's first step waits for its integrator, not for the fused step (about 2 s of
        compilation, mostly LLVM re-optimising what it links)."""
        future = self._compiling
        if future is not None:
            if not future.done():
                return None
            self._compiling = None
            self._install(future.result())
            return self.bound
        if kernel_compiled(self.fused):
            return self.bind(model_params, task_params)
        self._separate_steps += 1
        if self._separate_steps <= SEPARATE_FIRST:
            return None
        self._compiling = future = Future()
        thread = threading.Thread(
            target=self._background, name="fused step", args=(future, model_params, task_params)
        )
        _COMPILING.add(thread)
        thread.start()
        return None

    @property
    def compiling(self) -> bool:
        """Whether the fused step is compiling in the background now."""
        return self._compiling is not None

    def _background(self, future: Future, model_params, task_params) -> None:
        try:
            future.set_result(self._compile(model_params, task_params))
        except Exception as exc:  # the next step raises it
            future.set_exception(exc)
        finally:
            _COMPILING.discard(threading.current_thread())


def shared_and_rows(model_params):
    """(p, P) as the kernels over rows take the store's `model_params`: the shared vector
    and None, or a row (its type) and every row's own."""
    if model_params.ndim == 1:
        return model_params, None
    return model_params[0], model_params


_COMPILING: set[threading.Thread] = set()


def wait_for_background() -> None:
    """Wait until every fused step compiling in the background has compiled (or failed)."""
    for thread in list(_COMPILING):
        thread.join()


# a forked child would inherit numba's compiler lock held by a thread it does not have
os.register_at_fork(before=wait_for_background)
