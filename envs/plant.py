"""The bound plant: a task bound to its compiled model and parameters, built once per env.

`Plant.build(task, options)` takes the env's options (listed once, in `ENV_OPTIONS`, and
the model's parameters by name), compiles the task's model with the parameters, resolves
the declared numbers (bounds, limits, ranges given as functions of p), checks the
declaration against the model (`envs.checks`), and turns the observation features into a
table of column operations for the runtime's kernel. It is the one home of what the
runtime and the agents need of a task: the parameter record, start sampling and reset-option
checks, the inverse maps (observation -> state and goal), the operating state and input, the
action scaling, and the env's own step (`step`; a batched simulator of it is
`env.simulator(n)`, a runtime of this plant).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import cache, cached_property
from typing import Any

import numpy as np

import dynamics
from dynamics.checks import did_you_mean
from dynamics.model import factory_target
from dynamics.system import method_tableau

from . import checks
from .checks import checked_rows, positive_float, positive_int, real_array
from .perturb import Perturbations
from .randomize import Randomization, add_context, warn_nominal
from .task import Angle, AngleError, Derived, Task, Value, resolve

# column operations of the observation kernel: (op, source, second source)
OP_VALUE, OP_COS, OP_SIN, OP_COS_DIFF, OP_SIN_DIFF = range(5)
ENV_OPTIONS = {
    "render_mode": "None, 'human' or 'rgb_array' (the vector env: 'rgb_array')",
    "control_period": "seconds per env step (default: the task's)",
    "substeps": "integrator steps per env step (default: the task's)",
    "integrator": "'dop853' or 'rk4' (default: the task's)",
    "num_threads": "threads stepping a vector env's copies (default 1; same results)",
    "max_input": "input limits: one number, or one per actuated input, each a bound or (low, high)",
    "randomize": "model parameters each copy draws, {name: (low, high)} (uniform, absolute, "
    "at every reset) or {name: distribution} (envs.randomize: uniform, log-uniform, truncated "
    "normal, choice; absolute, scale or offset; at reset, construction or every k steps); {} "
    "steps each copy with its own values, set by reset(options={'params': ...}); default "
    "None: the task's `randomize` (None there: every copy has the env's values); False: off",
    "observe_params": "True: the randomised parameters' values appended to the observation "
    "(context), bounded by their distributions' supports; or a tuple of their names "
    "(default False)",
    "perturb": "observation and action noise, motor response, delay, pushes: a dict with "
    "keys obs_noise, action_noise, motor_k, delay, push (see envs.perturb; default None: off)",
}
"""The env options besides the model's parameters (by name), with what they mean."""


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
    if callable(model) or isinstance(model, staticmethod):
        target = factory_target(model)  # importable: keyed by its source file, and a warm
        if target is None:  # cache never rebuilds the spec (as for the registered models)
            return dynamics.Model(model)
        return dynamics.Model(target, name=target.rsplit(".", 1)[-1].split(":")[-1])
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
            hint = did_you_mean(key, known + list(ENV_OPTIONS))
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


# ---- the plant ---------------------------------------------------------------------------
@dataclass
class Plant:
    """The bound plant: see the module docstring. Arrays are float64 unless noted."""

    task: Task
    system: Any
    p: np.record
    state_names: tuple[str, ...]
    row_names: tuple[str, ...]  # the columns of the rows x the task functions see
    output_index: np.ndarray  # int64: model output columns appended to x
    actuated: np.ndarray  # int64: model input index of each action component
    input_low: np.ndarray  # physical limits of each actuated input: action -1 ...
    input_high: np.ndarray  # ... and action 1
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
    unobserved: tuple[str, ...]  # coordinates the observation does not show
    _state_from_obs: tuple
    _goal_from_obs: tuple
    control_period: float = 0.05
    substeps: int = 10
    integrator: str = "dop853"
    num_threads: int = 1
    options: dict = field(default_factory=dict)  # the options it was built with
    # the declared randomisation (envs.randomize), or None: every copy steps with
    # `system`'s values (the task functions' record `p` is `system`'s unless `p_follows`)
    randomize: Randomization | None = None
    context: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))
    # int64 (k, 2): observation column, parameter column of each context feature
    p_follows: bool = False  # the task functions' `p` follows each copy's values
    # the checked `perturb=` option (envs.perturb), or None: the env's runtime applies it
    perturb: Any = None

    @classmethod
    def build(cls, task: Task, options: dict[str, Any] | None = None) -> Plant:
        """The plant of `task` for the env options `options` (see `ENV_OPTIONS`; the rest
        are the model's parameters by name)."""
        if not isinstance(task, Task):
            raise TypeError(f"task must be an envs.Task, got {type(task).__name__}.")
        options = dict(options or {})
        opts = {k: options.pop(k) for k in list(options) if k in ENV_OPTIONS and k != "render_mode"}
        options.pop("render_mode", None)
        plant = build_plant(task, options, opts.get("max_input"))
        plant.options = opts
        get = opts.get
        plant.control_period = positive_float(
            "control_period",
            task.control_period if get("control_period") is None else get("control_period"),
        )
        plant.substeps = positive_int(
            "substeps", task.substeps if get("substeps") is None else get("substeps")
        )
        plant.integrator = task.integrator if get("integrator") is None else get("integrator")
        method_tableau(plant.integrator)  # ValueError naming the known integrators
        threads = get("num_threads")
        plant.num_threads = 1 if threads is None else positive_int("num_threads", threads)
        declared = task.randomize if get("randomize") is None else get("randomize")
        if declared is not False and declared is not None:
            plant.randomize = Randomization.declare(plant.system, declared)
            max_input = opts.get("max_input")
            rebuild = lambda values: build_plant(task, {**options, **values}, max_input)  # noqa: E731
            plant.p_follows = warn_nominal(plant, rebuild)
        add_context(plant, get("observe_params"))
        plant.perturb = Perturbations.parse(get("perturb"), plant)
        return plant

    @property
    def obs_size(self) -> int:
        return len(self.obs_low)

    @property
    def max_input(self) -> np.ndarray:
        """The largest magnitude of each actuated input (action +-1 for symmetric limits)."""
        return np.maximum(np.abs(self.input_low), np.abs(self.input_high))

    @property
    def input_mid(self) -> np.ndarray:
        """The input of action 0: the middle of each input's range."""
        return (self.input_low + self.input_high) / 2

    @property
    def input_half(self) -> np.ndarray:
        """Half of each input's range: input = mid + action * half."""
        return (self.input_high - self.input_low) / 2

    @property
    def lowest_reward(self) -> float:
        """The lowest reward one step can pay (the sum of the terms' lower bounds)."""
        return float(self.term_low.sum())

    @cached_property
    def time_dependent(self) -> bool:
        """Whether the dynamics depend on time explicitly (a prescribed motion, a drive):
        the accelerations at sample states differ at other times."""
        x = self.sample_states(4)
        u = np.zeros((len(x), self.system.n_u))
        a0 = self.system.accelerations(0.0, x, u)
        period = self.control_period
        return any(
            not np.allclose(self.system.accelerations(t, x, u), a0, rtol=1e-12, atol=1e-12)
            for t in (0.37 * period, 1.3, 7.9)
        )

    def resolve(self, value) -> float:
        """A declared number at this plant's parameters (see `envs.task.resolve`)."""
        return resolve(value, self.p)

    # ---- actions and inputs --------------------------------------------------------------
    def action_to_input(self, action) -> np.ndarray:
        """Model input vector u for `action` (clipped to [-1, 1]); batched over leading axes."""
        a = np.clip(real_array(action, "action"), -1.0, 1.0)
        u = np.zeros(a.shape[:-1] + (self.system.n_u,))
        u[..., self.actuated] = self.input_mid + a * self.input_half
        return u

    def input_to_action(self, u) -> np.ndarray:
        """The action that applies model input u (unclipped inverse of `action_to_input`)."""
        return (real_array(u, "u")[..., self.actuated] - self.input_mid) / self.input_half

    # ---- simulation ----------------------------------------------------------------------
    def step(self, x, u, t=0.0) -> np.ndarray:
        """The state one control period after x under constant inputs u from time t, by the
        env's own integrator and substeps (batched over leading axes)."""
        return self.system.step(x, u, self.control_period, self.substeps, t, method=self.integrator)

    # ---- inverse maps --------------------------------------------------------------------
    def state_from_observation(self, obs: np.ndarray) -> np.ndarray:
        """States (N, 2n) from observations (N, n_obs): angles by atan2, values as they
        are, unobserved rates from the constraints (or 0). Unobserved coordinates are 0:
        agents that need them refuse or complete them (`require_observed`)."""
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

    def require_observed(self, agent: str, needed=None) -> None:
        """ValueError naming the coordinates an agent needs that the observation does not
        show (`needed`: state names the agent uses; None: every coordinate)."""
        needed = self.state_names if needed is None else needed
        missing = [c for c in self.unobserved if c in needed]
        if missing:
            raise checks.Unsupported(
                f"{agent} rebuilds the state from the observation, and task "
                f"{self.task.name!r} does not observe {missing}: observe them (e.g. "
                f"Value({missing[0]!r}, ...)), or leave them out of what the agent regulates."
            )

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
            if isinstance(value, str) and value in self.goal_names:
                x0[:, i] = g[:, self.goal_names.index(value)]
            else:
                x0[:, i] = resolve(value, self.p)
        return x0

    def operating_input(self, x0: np.ndarray, t: float = 0.0) -> np.ndarray:
        """Inputs that hold x0 with zero accelerations: least squares over the actuated
        inputs (accelerations are affine in the inputs, so one evaluation per input gives
        the exact input matrix). Zero where no input is needed."""
        s, idx = self.system, list(self.actuated)
        u = np.zeros(x0.shape[:-1] + (s.n_u,))
        a0 = s.accelerations(t, x0, u)
        cols = []
        for j in idx:
            e = u.copy()
            e[..., j] = 1.0
            cols.append(s.accelerations(t, x0, e) - a0)
        B = np.stack(cols, axis=-1)  # (..., n_q, n_a)
        u[..., idx] = -(np.linalg.pinv(B) @ a0[..., None])[..., 0]
        return u

    def operating_point(self, g: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(x0, u0) for goals g and states x (rows), checked: inputs within the declared
        limits hold x0 (`envs.checks.check_equilibrium`)."""
        x0 = self.operating_state(g, x)
        u0 = self.operating_input(x0)
        checks.check_equilibrium(self, x0, u0)
        return x0, u0

    # ---- starting states -----------------------------------------------------------------
    def sample_start(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """One starting state and goal from the task's start distribution (checked)."""
        start = self.task.start
        if callable(start):
            x, g = start(rng, self.p)
            x, g = np.asarray(x, dtype=np.float64), np.asarray(g, dtype=np.float64)
            n_x, n_g = len(self.state_names), len(self.goal_names)
            if (
                x.shape != (n_x,)
                or g.shape != (n_g,)
                or not (np.isfinite(x).all() and np.isfinite(g).all())
            ):
                raise ValueError(
                    f"Task {self.task.name!r}: `start` must return a finite state of shape "
                    f"({n_x},) and goal of shape ({n_g},); got {x.tolist()} and {g.tolist()}."
                )
            return x, g
        x = np.zeros(len(self.state_names))
        for name, (lo, hi) in start.items():
            x[self.state_names.index(name)] = rng.uniform(resolve(lo, self.p), resolve(hi, self.p))
        g = np.array([rng.uniform(lo, hi) for lo, hi in zip(self.goal_low, self.goal_high)])
        return x, g

    def sample_states(self, k: int) -> np.ndarray:
        """k starting states (a fixed seed), for checks."""
        rng = np.random.default_rng(12345)
        x = np.array([self.sample_start(rng)[0] for _ in range(k)])
        return self.system.project(x) if self.system.n_c else x

    def sample_rows(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """k rows the task functions see (starting states and their outputs) and goals."""
        rng = np.random.default_rng(12345)
        drawn = [self.sample_start(rng) for _ in range(k)]
        x = np.array([d[0] for d in drawn]).reshape(k, -1)
        g = np.array([d[1] for d in drawn]).reshape(k, len(self.goal_names))
        if self.system.n_c:
            x = self.system.project(x)
        if len(self.output_index):
            y = self.system.outputs(0.0, x, np.zeros((k, self.system.n_u)))
            cols = [y[name] for name in self.task.outputs]
            x = np.concatenate([x, np.stack(cols, axis=-1).reshape(k, -1)], axis=1)
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

    def start_rows(
        self, rngs, options: dict | None, rows: list[int], batch: int | None, params=None
    ):
        """Starting states and goals of `rows`: options['state'] / options['goal'] where
        given (checked: shape, finite, state within the task's limits, goal within its
        ranges), else drawn from the task's start distribution with each row's generator.
        Options are checked before any generator draws. Constrained models' states are
        projected onto their velocity constraints (with each row's parameters `params`,
        (len(rows), n_p), where given)."""
        system = self.system
        options = options or {}
        if not isinstance(options, dict):
            raise TypeError(f"reset options must be a dict, got {type(options).__name__}.")
        unknown = set(options) - {"state", "goal", "params"}
        if unknown:
            raise ValueError(
                f"Unknown reset option(s) {sorted(unknown)}; known: 'state', 'goal', 'params'."
            )
        x_given = g_given = None
        if options.get("state") is not None:
            x_given = checked_rows(
                options["state"], (system.state_size,), "options['state']", batch
            )[rows]
            over = np.abs(x_given) > self.limits
            if over.any():
                i = int(np.argwhere(over)[0][1])
                raise ValueError(
                    f"options['state'] component {self.state_names[i]!r} = "
                    f"{x_given[over][0]:.6g} is beyond the task's limit {self.limits[i]:.6g}."
                )
        if options.get("goal") is not None:
            g_given = checked_rows(
                options["goal"], (len(self.goal_names),), "options['goal']", batch
            )[rows]
            for row in g_given:
                self.check_goal(row)
        drawn = [self.sample_start(rngs[i]) for i in rows]
        x = np.array([d[0] for d in drawn]).reshape(len(rows), system.state_size)
        g = np.array([d[1] for d in drawn]).reshape(len(rows), len(self.goal_names))
        x = x if x_given is None else x_given
        g = g if g_given is None else g_given
        if system.n_c and params is not None:  # onto each row's own constraints
            x = np.array([
                system.with_parameters(**dict(zip(system.parameters, row))).project(xi)
                for xi, row in zip(x, params)
            ]).reshape(x.shape)  # fmt: skip
        elif system.n_c:
            x = system.project(x)
        return x, g


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


def build_plant(task: Task, params: dict, max_input=None) -> Plant:
    """Compile `task`'s model with `params`, resolve everything the runtime needs and
    check the declaration against the model (`envs.checks.check_with_model`)."""
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
        constants = task.constants(system)
        if not isinstance(constants, Mapping):
            raise checks.DeclarationError(
                f"Task {task.name!r}: `constants` must return {{name: number}}, got {constants!r}."
            )
        shadowed = sorted(set(constants) & set(values))
        if shadowed:
            raise checks.DeclarationError(
                f"Task {task.name!r}: `constants` {shadowed} shadow parameters of "
                f"{system.name}; the task functions would see other values than the physics. "
                "Rename them."
            )
        for k, v in constants.items():
            if not (isinstance(k, str) and k.isidentifier()):
                raise checks.DeclarationError(
                    f"Task {task.name!r}: `constants` name {k!r} is not an identifier."
                )
            try:
                values[k] = float(v)
            except (TypeError, ValueError):
                raise checks.DeclarationError(
                    f"Task {task.name!r}: `constants[{k!r}]` must be a number, got {v!r}."
                ) from None
            if not np.isfinite(values[k]):
                raise checks.DeclarationError(
                    f"Task {task.name!r}: `constants[{k!r}]` must be finite, got {v!r}."
                )
    p = parameter_record(values)

    for name in task.actuated:
        if name not in system.inputs:
            raise ValueError(
                f"Task {task.name!r} actuates {name!r}; {system.name}'s inputs are "
                f"{', '.join(system.inputs) or 'none'}."
            )
    actuated = np.array([system.inputs.index(k) for k in task.actuated], dtype=np.int64)
    limits_in = task.max_input if max_input is None else max_input
    input_low, input_high = _input_limits(limits_in, p, len(actuated))

    limits = np.full(2 * n, np.inf)
    for name, bound in task.limits.items():
        limits[_index(task, names, name, "limits")] = resolve(bound, p)
    for name in task.start if isinstance(task.start, dict) else ():
        _index(task, names, name, "start")

    goal_names = tuple(g.name for g in task.goal)
    clash = set(goal_names) & set(p.dtype.names)
    if clash:
        raise checks.DeclarationError(
            f"Task {task.name!r}: goal names {sorted(clash)} are also parameter names."
        )
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
        hint = did_you_mean(name, known)
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
    unobserved = tuple(names[i] for i in range(n) if i not in observed)
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
    plant = Plant(
        task=task,
        system=system,
        p=p,
        state_names=names,
        row_names=row_names,
        output_index=output_index,
        actuated=actuated,
        input_low=input_low,
        input_high=input_high,
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
        unobserved=unobserved,
        _state_from_obs=(angles_x, values_x, unobserved_rates),
        _goal_from_obs=(angles_g, values_g, fixed, missing),
    )
    checks.check_with_model(plant)
    return plant


def _index(task: Task, names: tuple[str, ...], name: str, where: str) -> int:
    if name not in names:
        hint = did_you_mean(name, names)
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


def _input_limits(value, p, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Resolved, checked (low, high) limits of the actuated inputs: each declared as a
    bound b (the range [-b, b]) or a (low, high) pair; one value serves every input."""
    if callable(value):
        value = value(p)
    if (
        isinstance(value, (str, bytes))
        or not np.ndim(value)
        and not isinstance(value, (tuple, list))
    ):
        items = [value] * n
    else:
        items = list(value)
    if any(
        isinstance(v, (bool, complex, np.complexfloating))
        for v in np.ravel(np.array(items, dtype=object))
    ):
        raise TypeError(f"max_input must be real numbers, got {value!r}.")
    if len(items) != n:
        raise ValueError(
            f"max_input must be a number or {n} numbers or (low, high) pairs, got {value!r}."
        )
    low, high = np.empty(n), np.empty(n)
    try:
        for k, v in enumerate(items):
            if isinstance(v, (tuple, list, np.ndarray)) and len(v) == 2:
                low[k], high[k] = resolve(v[0], p), resolve(v[1], p)
            else:
                high[k] = resolve(v, p)
                low[k] = -high[k]
    except (TypeError, ValueError):
        raise ValueError(
            f"max_input must be a number or {n} numbers or (low, high) pairs, got {value!r}."
        ) from None
    if not (np.isfinite(low).all() and np.isfinite(high).all() and (low < high).all()):
        raise ValueError(
            f"max_input must be positive and finite (or low < high, finite), got {value!r}."
        )
    return low, high
