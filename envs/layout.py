"""A task resolved against its compiled model: every number, index and map the runtime uses.

`build_layout(task, params)` compiles the task's model with `params`, resolves the declared
numbers (bounds, limits, ranges given as functions of p), and turns the observation
features into a table of column operations for the runtime's kernel, with their bounds and
the inverse maps (observation -> state and goal) that LQR and heuristics use.
"""

from __future__ import annotations

import difflib
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from typing import Any

import numpy as np

import dynamics

from .task import Angle, AngleError, Derived, Task, Value, resolve

# column operations of the observation kernel: (op, source, second source)
OP_VALUE, OP_COS, OP_SIN, OP_COS_DIFF, OP_SIN_DIFF = range(5)
ENV_OPTIONS = (
    "render_mode",
    "control_period",
    "substeps",
    "integrator",
    "num_threads",
    "max_input",
)


def state_names(system) -> tuple[str, ...]:
    """Names of the state components [q, qdot]: the coordinates, then '<name>_dot'."""
    return tuple(system.coordinates) + tuple(f"{c}_dot" for c in system.coordinates)


# ---- the model ---------------------------------------------------------------------------
@cache
def _model(model) -> dynamics.Model:
    if isinstance(model, str):
        return dynamics.get_model(model)
    if isinstance(model, dynamics.Model):
        return model
    if callable(model):
        module, qualname = getattr(model, "__module__", None), getattr(model, "__qualname__", "")
        if module and "<" not in qualname and module != "__main__":
            # an importable factory: keyed by its source file, so a warm cache never
            # rebuilds the spec (as for the registered models)
            return dynamics.Model(f"{module}:{qualname}", name=model.__name__)
        return dynamics.Model(model)
    raise TypeError(
        "A task's model must be a registered model name, a dynamics.Model, a ModelSpec "
        f"factory or a dynamics.System; got {type(model).__name__}."
    )


def compile_model(model, params: dict) -> dynamics.System:
    """The task's model compiled with `params` (a System is re-parameterised)."""
    if isinstance(model, dynamics.System):
        system = model
    else:
        system = _model(model).compile()
    known = list(system.parameters)
    for key in params:
        if key not in known:
            close = difflib.get_close_matches(key, known + list(ENV_OPTIONS), n=1)
            hint = f" Did you mean {close[0]!r}?" if close else ""
            raise ValueError(
                f"Unknown argument {key!r}.{hint} Known: {', '.join(ENV_OPTIONS)} and the "
                f"parameters of {system.name}: {', '.join(known)}."
            )
    return system.with_parameters(**params) if params else system


def parameter_record(values: dict[str, float]) -> np.record:
    """The parameters as a numpy record: read by name (`p.m1`) in Python and in numba."""
    names = list(values)
    dtype = [(n, np.float64) for n in names]
    return np.rec.array([tuple(float(values[n]) for n in names)], dtype=dtype)[0]


# ---- the layout --------------------------------------------------------------------------
@dataclass
class Layout:
    """The resolved task: see the module docstring. Arrays are float64 unless noted."""

    task: Task
    system: Any
    p: np.record
    state_names: tuple[str, ...]
    row_names: tuple[str, ...]  # the columns of the rows x the task functions see
    output_index: np.ndarray  # int64: model output columns appended to x
    actuated: np.ndarray  # int64: model input index of each action component
    max_input: np.ndarray
    limits: np.ndarray  # (2n,): divergence bound on |x_i| (inf: none)
    goal_names: tuple[str, ...]
    goal_low: np.ndarray
    goal_high: np.ndarray
    ops: np.ndarray  # int64 (n_cols, 4): column, op, source, second source
    derived: tuple[tuple[int, Callable], ...]  # (column, fn)
    obs_low: np.ndarray
    obs_high: np.ndarray
    columns: tuple[tuple[str, float, float, str], ...]  # label, low, high, unit
    term_low: np.ndarray
    term_high: np.ndarray
    periodic: np.ndarray  # bool (n_q,): coordinates observed as angles
    _state_from_obs: tuple
    _goal_from_obs: tuple

    @property
    def obs_size(self) -> int:
        return len(self.obs_low)

    @property
    def lowest_reward(self) -> float:
        """The lowest reward one step can pay (the sum of the terms' lower bounds)."""
        return float(self.term_low.sum())

    # ---- inverse maps --------------------------------------------------------------------
    def state_from_observation(self, obs: np.ndarray) -> np.ndarray:
        """States (N, 2n) from observations (N, n_obs): angles by atan2, values as they
        are; unobserved coordinates 0 and unobserved rates from the constraints (or 0)."""
        obs = np.asarray(obs, dtype=np.float64)
        x = np.zeros((len(obs), len(self.state_names)))
        angles, values, unobserved_rates = self._state_from_obs
        for i, c, s in angles:
            x[:, i] = np.arctan2(obs[:, s], obs[:, c])
        for i, col in values:
            x[:, i] = obs[:, col]
        if len(unobserved_rates) and self.system.n_c:
            x = _rates_from_constraints(self.system, x, unobserved_rates)
        return x

    def goal_from_observation(self, obs: np.ndarray) -> np.ndarray:
        """Goals (N, n_g) from observations; fixed goal components need no observation."""
        obs = np.asarray(obs, dtype=np.float64)
        g = np.zeros((len(obs), len(self.goal_names)))
        angles, values, fixed, missing = self._goal_from_obs
        if missing:
            raise ValueError(
                f"Task {self.task.name!r} does not observe goal component(s) {missing}, so "
                "the goal cannot be read from an observation."
            )
        for j, c, s in angles:
            g[:, j] = np.arctan2(obs[:, s], obs[:, c])
        for j, col in values:
            g[:, j] = obs[:, col]
        for j, v in fixed:
            g[:, j] = v
        return g

    # ---- operating point -----------------------------------------------------------------
    def operating_state(self, g: np.ndarray, x: np.ndarray) -> np.ndarray:
        """The state (N, 2n) the task regulates to, for goals g and current states x."""
        op = self.task.operating_point
        if op is None:
            raise ValueError(
                f"Task {self.task.name!r} declares no operating_point; LQR and the "
                "heuristics need one (a dict {coordinate: value or goal name} or a function)."
            )
        g, x = np.atleast_2d(g), np.atleast_2d(x)
        if callable(op):
            return np.asarray(op(g, x, self.system), dtype=np.float64).reshape(len(g), -1)
        x0 = np.zeros((len(g), len(self.state_names)))
        for name, value in op.items():
            i = self.state_names.index(name)
            if isinstance(value, str):
                x0[:, i] = g[:, self.goal_names.index(value)]
            else:
                x0[:, i] = resolve(value, self.p)
        return x0

    # ---- starting states -----------------------------------------------------------------
    def sample_start(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """One starting state and goal from the task's start distribution."""
        start = self.task.start
        if callable(start):
            x, g = start(rng, self.p)
            return np.asarray(x, dtype=np.float64), np.asarray(g, dtype=np.float64)
        x = np.zeros(len(self.state_names))
        for name, (lo, hi) in start.items():
            x[self.state_names.index(name)] = rng.uniform(resolve(lo, self.p), resolve(hi, self.p))
        g = np.array([rng.uniform(lo, hi) for lo, hi in zip(self.goal_low, self.goal_high)])
        return x, g

    def check_goal(self, g: np.ndarray) -> None:
        """ValueError unless every goal component lies in its declared range."""
        for j, name in enumerate(self.goal_names):
            if self.task.goal[j].angle:
                continue
            lo, hi = self.goal_low[j], self.goal_high[j]
            if not lo - 1e-12 * max(1.0, abs(lo)) <= g[j] <= hi + 1e-12 * max(1.0, abs(hi)):
                raise ValueError(
                    f"Goal component {name!r} must lie in [{lo:.6g}, {hi:.6g}], got {g[j]:.6g}."
                )


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
    for b in range(len(x)):
        x[b, rates] += np.linalg.lstsq(B[b], -r0[b], rcond=None)[0]
    return x


def build_layout(task: Task, params: dict, max_input=None) -> Layout:
    """Compile `task`'s model with `params` and resolve everything the runtime needs."""
    system = compile_model(task.model, params)
    names = state_names(system)
    n = system.n_q
    for name in task.outputs:
        if name not in system.output_names:
            raise ValueError(
                f"Task {task.name!r} asks for output {name!r}; {system.name} has "
                f"{', '.join(system.output_names) or 'none'}."
            )
    row_names = names + tuple(task.outputs)
    output_index = np.array([system.output_names.index(k) for k in task.outputs], dtype=np.int64)
    values = dict(system.parameters)
    if task.constants is not None:
        values.update({k: float(v) for k, v in task.constants(system).items()})
    p = parameter_record(values)

    for name in task.actuated:
        if name not in system.inputs:
            raise ValueError(
                f"Task {task.name!r} actuates {name!r}; {system.name}'s inputs are "
                f"{', '.join(system.inputs) or 'none'}."
            )
    actuated = np.array([system.inputs.index(k) for k in task.actuated], dtype=np.int64)
    limits_in = task.max_input if max_input is None else max_input
    max_in = _input_limits(limits_in, p, len(actuated))

    limits = np.full(2 * n, np.inf)
    for name, bound in task.limits.items():
        limits[_index(task, names, name, "limits")] = resolve(bound, p)
    for name in task.start if isinstance(task.start, dict) else ():
        _index(task, names, name, "start")

    goal_names = tuple(g.name for g in task.goal)
    clash = set(goal_names) & set(row_names)
    if clash:
        raise ValueError(f"Task {task.name!r}: goal names {sorted(clash)} are also state names.")
    goal_low = np.array([resolve(g.low, p) for g in task.goal])
    goal_high = np.array([resolve(g.high, p) for g in task.goal])

    nx = len(row_names)
    ops, derived, columns, lows, highs = [], [], [], [], []
    periodic = np.zeros(n, dtype=bool)
    angles_x, values_x, angles_g, values_g = [], [], [], []

    def source(name: str, feature) -> int:
        if name in row_names:
            return row_names.index(name)
        if name in goal_names:
            return nx + goal_names.index(name)
        known = list(row_names) + list(goal_names)
        close = difflib.get_close_matches(name, known, n=1)
        hint = f" Did you mean {close[0]!r}?" if close else ""
        raise ValueError(
            f"Task {task.name!r}: {type(feature).__name__}({name!r}) names nothing known.{hint} "
            f"State and outputs: {', '.join(row_names)}; goal: {', '.join(goal_names) or 'none'}."
        )

    def add(op, src, src2, label, lo, hi, unit):
        col = len(columns)
        ops.append((col, op, src, src2))
        columns.append((label, lo, hi, unit))
        lows.append(lo)
        highs.append(hi)
        return col

    for f in task.observation:
        if isinstance(f, Angle):
            s = source(f.name, f)
            c = add(OP_COS, s, 0, f"cos {f.name}", -1.0, 1.0, "")
            add(OP_SIN, s, 0, f"sin {f.name}", -1.0, 1.0, "")
            if s < nx:
                if s >= n:
                    raise ValueError(f"Task {task.name!r}: Angle({f.name!r}) is not a coordinate.")
                periodic[s] = True
                angles_x.append((s, c, c + 1))
            else:
                angles_g.append((s - nx, c, c + 1))
        elif isinstance(f, AngleError):
            s, s2 = source(f.name, f), source(f.goal, f)
            label = f"{f.name} - {f.goal}"
            add(OP_COS_DIFF, s, s2, f"cos({label})", -1.0, 1.0, "")
            add(OP_SIN_DIFF, s, s2, f"sin({label})", -1.0, 1.0, "")
        elif isinstance(f, Value):
            s = source(f.name, f)
            if f.bound is not None:
                bound = resolve(f.bound, p)
            elif s < 2 * n:
                bound = limits[s]
            elif s >= nx:
                j = s - nx
                bound = max(abs(goal_low[j]), abs(goal_high[j]))
            else:
                bound = np.inf
            if not np.isfinite(bound):
                raise ValueError(
                    f"Task {task.name!r}: Value({f.name!r}) needs a finite bound (give "
                    f"`bound=`, or a limit for it in `limits`)."
                )
            col = add(OP_VALUE, s, 0, f.name, -bound, bound, f.unit or _unit(task, f.name))
            if s < 2 * n:
                values_x.append((s, col))
            elif s >= nx:
                values_g.append((s - nx, col))
        elif isinstance(f, Derived):
            lo, hi = resolve(f.low, p), resolve(f.high, p)
            col = add(-1, 0, 0, f.name, lo, hi, f.unit)
            ops.pop()
            derived.append((col, f.fn))
        else:
            raise TypeError(f"Task {task.name!r}: unknown observation feature {f!r}.")
    observed = {i for i, *_ in angles_x} | {i for i, _ in values_x}
    unobserved_rates = [n + i for i in range(n) if n + i not in observed]
    goal_seen = {j for j, *_ in angles_g} | {j for j, _ in values_g}
    fixed = [(j, goal_low[j]) for j in range(len(goal_names)) if goal_low[j] == goal_high[j]]
    missing = [
        goal_names[j]
        for j in range(len(goal_names))
        if j not in goal_seen and goal_low[j] != goal_high[j]
    ]
    term_low = np.array([resolve(t.low, p) for t in task.terms])
    term_high = np.array([resolve(t.high, p) for t in task.terms])
    if not (term_low <= term_high).all():
        raise ValueError(f"Task {task.name!r}: a reward term's low bound exceeds its high.")
    return Layout(
        task=task,
        system=system,
        p=p,
        state_names=names,
        row_names=row_names,
        output_index=output_index,
        actuated=actuated,
        max_input=max_in,
        limits=limits,
        goal_names=goal_names,
        goal_low=goal_low,
        goal_high=goal_high,
        ops=np.array(ops, dtype=np.int64).reshape(-1, 4),
        derived=tuple(derived),
        obs_low=np.array(lows),
        obs_high=np.array(highs),
        columns=tuple(columns),
        term_low=term_low,
        term_high=term_high,
        periodic=periodic,
        _state_from_obs=(angles_x, values_x, unobserved_rates),
        _goal_from_obs=(angles_g, values_g, fixed, missing),
    )


def _index(task: Task, names: tuple[str, ...], name: str, where: str) -> int:
    if name not in names:
        close = difflib.get_close_matches(name, names, n=1)
        hint = f" Did you mean {close[0]!r}?" if close else ""
        raise ValueError(
            f"Task {task.name!r}: unknown state component {name!r} in `{where}`.{hint} "
            f"Known: {', '.join(names)}."
        )
    return names.index(name)


def _unit(task: Task, name: str) -> str:
    """A goal component's declared unit ('' for other names)."""
    for g in task.goal:
        if g.name == name:
            return g.unit
    return ""


def _input_limits(value, p, n: int) -> np.ndarray:
    """Resolved, checked limits of the actuated inputs (one per action component)."""
    if callable(value):
        value = value(p)
    items = list(value) if np.ndim(value) else [value] * n
    if any(isinstance(v, (bool, complex, np.complexfloating)) for v in items):
        raise TypeError(f"max_input must be real numbers, got {value!r}.")
    try:
        limits = np.array([resolve(v, p) for v in items], dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"max_input must be a number or {n} numbers, got {value!r}.") from None
    if limits.shape != (n,):
        raise ValueError(f"max_input must be a number or {n} numbers, got {value!r}.")
    if not (np.isfinite(limits).all() and (limits > 0).all()):
        raise ValueError(f"max_input must be positive and finite, got {value!r}.")
    return limits
