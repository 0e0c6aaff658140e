"""The observation compiler: a task's declared features turned into a table of column
operations, once per plant, and the kernel that applies the table to rows.

Each feature gives one or two columns; each column is one row of `Observation.ops`,
(column, op, source, second source), where a source indexes the row [x | g] (the state
and declared outputs x, then the goal g) or, for `OP_CONTEXT`, the parameter vector:

| op | column | written by |
|---|---|---|
| `OP_VALUE` | the source as it is | `observe` |
| `OP_COS`, `OP_SIN` | cos, sin of the source (an `Angle`) | `observe` |
| `OP_COS_DIFF`, `OP_SIN_DIFF` | cos, sin of source - second source (an `AngleError`) | `observe` |
| `OP_DERIVED` | a `Derived` feature's function | the runtime, after `observe` |
| `OP_CONTEXT` | an observed parameter (`observe_params=`) | the runtime, at a write |

Every column is clipped into its bounds (`low`, `high`). The same pass records what the
inverse maps (observation -> state and goal) need.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numba import njit

from dynamics.checks import did_you_mean

from .task import Angle, AngleError, Derived, Task, Value, resolve


def read_only(record) -> None:
    """Make the arrays of the frozen dataclass `record` (and those inside its tuples)
    read-only, so that nobody writes what a frozen record holds."""

    def freeze(value):
        if isinstance(value, np.ndarray):
            value.flags.writeable = False
        elif isinstance(value, tuple):
            for v in value:
                freeze(v)

    for field in dataclasses.fields(record):
        freeze(getattr(record, field.name))


OP_VALUE, OP_COS, OP_SIN, OP_COS_DIFF, OP_SIN_DIFF, OP_DERIVED, OP_CONTEXT = range(7)


@dataclass(frozen=True)
class Context:
    """An observed model parameter (the env option `observe_params`), bounded by the
    values its distribution reaches (`envs.randomize.Randomization.support`)."""

    name: str
    column: int  # in the order of `system.parameters`
    low: float
    high: float


@dataclass(frozen=True, eq=False)
class Observation:
    """A compiled observation (see the module docstring). Arrays are float64 unless noted."""

    ops: np.ndarray  # int64 (n_cols, 4): column, op, source, second source
    derived: tuple[tuple[int, Callable], ...]  # (column, fn) of each Derived feature
    context: np.ndarray  # int64 (k, 2): column, parameter column of each Context feature
    low: np.ndarray
    high: np.ndarray
    columns: tuple[tuple[str, float, float, str], ...]  # label, low, high, unit
    periodic: np.ndarray  # bool (n_q,): coordinates observed as angles
    unobserved: tuple[str, ...]  # coordinates the observation does not show
    state_map: tuple  # (angles, values, unobserved rates) of the state's inverse map
    goal_map: tuple  # (angles, values, fixed, missing) of the goal's inverse map

    def __post_init__(self):
        read_only(self)

    @property
    def size(self) -> int:
        return len(self.low)

    @property
    def declared(self) -> int:
        """The columns of the task's own features (the context's follow them)."""
        return self.size - len(self.context)


@njit(cache=True)
def observe(X, G, ops, low, high, out) -> None:
    """The columns `observe` writes (see the module docstring) of every row, clipped to
    their bounds; a source indexes [X | G]."""
    nx = X.shape[1]
    for b in range(X.shape[0]):
        for k in range(ops.shape[0]):
            col, op, s, s2 = ops[k, 0], ops[k, 1], ops[k, 2], ops[k, 3]
            if op == OP_DERIVED or op == OP_CONTEXT:
                continue
            v = X[b, s] if s < nx else G[b, s - nx]
            if op == OP_VALUE:
                r = v
            elif op == OP_COS:
                r = math.cos(v)
            elif op == OP_SIN:
                r = math.sin(v)
            else:
                w = X[b, s2] if s2 < nx else G[b, s2 - nx]
                d = v - w
                r = math.cos(d) if op == OP_COS_DIFF else math.sin(d)
            out[b, col] = min(max(r, low[col]), high[col])


class _Compiler:
    """One pass over the features: the table, the bounds and the inverse maps' tables."""

    def __init__(self, task: Task, n_q: int, row_names, goal_names, p, limits, goal_range):
        self.task, self.n, self.p, self.limits = task, n_q, p, limits
        self.row_names, self.goal_names = tuple(row_names), tuple(goal_names)
        self.goal_low, self.goal_high = goal_range
        self.nx = len(self.row_names)
        self.ops, self.derived, self.context, self.columns = [], [], [], []
        self.periodic = np.zeros(n_q, dtype=bool)
        self.angles_x, self.values_x, self.angles_g, self.values_g = [], [], [], []

    def source(self, name: str, feature) -> int:
        if name in self.row_names:
            return self.row_names.index(name)
        if name in self.goal_names:
            return self.nx + self.goal_names.index(name)
        known = list(self.row_names) + list(self.goal_names)
        hint = did_you_mean(name, known)
        raise ValueError(
            f"Task {self.task.name!r}: {type(feature).__name__}({name!r}) names nothing "
            f"known.{hint} State and outputs: {', '.join(self.row_names)}; goal: "
            f"{', '.join(self.goal_names) or 'none'}."
        )

    def add(self, op, src, src2, label, lo, hi, unit) -> int:
        col = len(self.columns)
        self.ops.append((col, op, src, src2))
        self.columns.append((label, lo, hi, unit))
        return col

    def angle(self, f: Angle) -> None:
        s = self.source(f.name, f)
        c = self.add(OP_COS, s, 0, f"cos {f.name}", -1.0, 1.0, "")
        self.add(OP_SIN, s, 0, f"sin {f.name}", -1.0, 1.0, "")
        if s >= self.nx:
            self.angles_g.append((s - self.nx, c, c + 1))
            return
        if s >= self.n:
            raise ValueError(f"Task {self.task.name!r}: Angle({f.name!r}) is not a coordinate.")
        self.periodic[s] = True
        self.angles_x.append((s, c, c + 1))

    def angle_error(self, f: AngleError) -> None:
        s, s2 = self.source(f.name, f), self.source(f.goal, f)
        label = f"{f.name} - {f.goal}"
        self.add(OP_COS_DIFF, s, s2, f"cos({label})", -1.0, 1.0, "")
        self.add(OP_SIN_DIFF, s, s2, f"sin({label})", -1.0, 1.0, "")

    def value(self, f: Value) -> None:
        s, n, nx = self.source(f.name, f), self.n, self.nx
        if f.bound is not None:
            bound = resolve(f.bound, self.p)
        elif s < 2 * n:
            bound = self.limits[s]
        elif s >= nx:
            bound = max(abs(self.goal_low[s - nx]), abs(self.goal_high[s - nx]))
        else:
            bound = np.inf
        if not np.isfinite(bound):
            raise ValueError(
                f"Task {self.task.name!r}: Value({f.name!r}) needs a finite bound (give "
                "`bound=`, or a limit for it in `limits`)."
            )
        unit = f.unit or next((g.unit for g in self.task.goal if g.name == f.name), "")
        col = self.add(OP_VALUE, s, 0, f.name, -bound, bound, unit)
        if s < 2 * n:
            self.values_x.append((s, col))
        elif s >= nx:
            self.values_g.append((s - nx, col))

    def derived_feature(self, f: Derived) -> None:
        lo, hi = resolve(f.low, self.p), resolve(f.high, self.p)
        col = self.add(OP_DERIVED, 0, 0, f.name, lo, hi, f.unit)
        self.derived.append((col, f.fn))

    def context_feature(self, f: Context) -> None:
        col = self.add(OP_CONTEXT, f.column, 0, f"param {f.name}", f.low, f.high, "")
        self.context.append((col, f.column))

    def result(self) -> Observation:
        n, names, goal_names = self.n, self.row_names, self.goal_names
        observed = {i for i, *_ in self.angles_x} | {i for i, _ in self.values_x}
        goal_seen = {j for j, *_ in self.angles_g} | {j for j, _ in self.values_g}
        lo, hi = self.goal_low, self.goal_high
        fixed = [(j, lo[j]) for j in range(len(goal_names)) if lo[j] == hi[j]]
        missing = [g for j, g in enumerate(goal_names) if j not in goal_seen and lo[j] != hi[j]]
        return Observation(
            ops=np.array(self.ops, dtype=np.int64).reshape(-1, 4),
            derived=tuple(self.derived),
            context=np.array(self.context, dtype=np.int64).reshape(-1, 2),
            low=np.array([c[1] for c in self.columns]),
            high=np.array([c[2] for c in self.columns]),
            columns=tuple(self.columns),
            periodic=self.periodic,
            unobserved=tuple(names[i] for i in range(n) if i not in observed),
            state_map=(
                self.angles_x,
                self.values_x,
                [n + i for i in range(n) if n + i not in observed],
            ),
            goal_map=(self.angles_g, self.values_g, fixed, missing),
        )


def compile_observation(
    task: Task,
    n_q: int,
    row_names,
    goal_names,
    p,
    limits,
    goal_range,
    context: tuple[Context, ...] = (),
) -> Observation:
    """The observation of `task`'s features, then the `context` features: `row_names`
    the columns of x, `p` the record the declared numbers resolve at, `limits` the
    state's bounds (a `Value` without a bound takes its limit), `goal_range` (low, high)."""
    c = _Compiler(task, n_q, row_names, goal_names, p, limits, goal_range)
    kinds = {Angle: c.angle, AngleError: c.angle_error, Value: c.value, Derived: c.derived_feature}
    for f in task.observation:
        if type(f) not in kinds:
            raise TypeError(f"Task {task.name!r}: unknown observation feature {f!r}.")
        kinds[type(f)](f)
    for f in context:
        c.context_feature(f)
    return c.result()


def state_from_observation(obs: Observation, system, state_size: int, o: np.ndarray):
    """States (N, 2n) from observations o (N, n_obs): angles by atan2, values as they
    are, unobserved rates from the constraints (or 0); unobserved coordinates 0."""
    o = np.asarray(o, dtype=np.float64)
    x = np.zeros((len(o), state_size))
    angles, values, unobserved_rates = obs.state_map
    for i, c, s in angles:
        x[:, i] = np.arctan2(o[:, s], o[:, c])
    for i, col in values:
        x[:, i] = o[:, col]
    if len(unobserved_rates) and system.n_c:
        x = _rates_from_constraints(system, x, unobserved_rates)
    return x


def goal_from_observation(obs: Observation, task: Task, n_goal: int, o: np.ndarray):
    """Goals (N, n_g) from observations o; fixed goal components need no observation."""
    o = np.asarray(o, dtype=np.float64)
    g = np.zeros((len(o), n_goal))
    angles, values, fixed, missing = obs.goal_map
    if missing:
        raise ValueError(
            f"Task {task.name!r} does not observe goal component(s) {missing}, so the goal "
            "cannot be read from an observation."
        )
    for j, c, s in angles:
        g[:, j] = np.arctan2(o[:, s], o[:, c])
    for j, col in values:
        g[:, j] = o[:, col]
    for j, v in fixed:
        g[:, j] = v
    return g


def _rates_from_constraints(system, x: np.ndarray, rates: list[int]) -> np.ndarray:
    """x with the rates `rates` solved from the velocity constraints B qdot + b = 0 (exact:
    the residual is affine in the rates), least squares where they do not fix them."""
    x = x.copy()
    r0 = system.constraint_residual(x)
    cols = []
    for i in rates:
        e = x.copy()
        e[:, i] += 1.0
        cols.append(system.constraint_residual(e) - r0)
    B = np.stack(cols, axis=-1)  # (N, n_c, len(rates))
    x[:, rates] -= (np.linalg.pinv(B) @ r0[:, :, None])[:, :, 0]  # each row's least squares
    return x
