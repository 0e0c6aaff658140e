"""The bound plant: a task bound to its compiled model and parameters, built once per env
and never written after.

`Plant.build(task, options)` composes parts each resolved once (`envs.resolved`): the
env's options split from the model's parameters, the model compiled with those
parameters (`Model.compile(**params)`), the parameter record the task functions read, the
input limits, the declared bounds and goal ranges, the randomisation declared
(`envs.randomize`), the observation compiled with its context features
(`envs.observation`) and the perturbations (`envs.perturb`); then checks the declaration
against the model (`envs.checks`). A `Plant` is a frozen dataclass: what varies per copy
(the parameters each copy steps with) lives in the runtime's parameter store
(`envs.parameters`), never here. It is the one home of what the runtime and the agents
need of a task: the parameter record, start sampling and reset-option checks
(`envs.starts`), the inverse maps (observation -> state and goal), the operating state and
input, the action scaling, and the env's own step (`step`; a batched simulator of it is
`env.simulator(n)`, a runtime of this plant).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from . import checks, nominal, observation, starts
from .checks import real_array
from .names import operating_state as call_operating_point
from .observation import Observation, compile_observation, read_only
from .perturb import Perturbations
from .randomize import Randomization, observed
from .resolved import (
    ENV_OPTIONS,
    compile_system,
    index_of,
    input_limits,
    parameter_record,
    split_options,
    state_names,
    stepping,
)
from .task import Task, resolve


@dataclass(frozen=True, eq=False)
class Plant:
    """The bound plant: see the module docstring. Arrays are float64 unless noted."""

    task: Task
    system: Any
    p: np.record  # the task functions' record: the parameters, then the task's constants
    options: dict  # the env options it was built with (`ENV_OPTIONS`)
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
    observation: Observation  # the compiled observation (envs.observation)
    term_low: np.ndarray
    term_high: np.ndarray
    control_period: float
    substeps: int
    integrator: str
    num_threads: int
    # the declared randomisation (envs.randomize), or None: every copy steps with
    # `system`'s values
    randomize: Randomization | None = None
    # the checked `perturb=` option (envs.perturb), or None: the env's runtime applies it
    perturb: Perturbations | None = None
    # with randomisation (envs.nominal): whether the task functions' record follows each
    # copy's values, and (bool (n_p,), where it does and the task has constants) the
    # parameters the task's constants depend on
    follows: bool = False
    constant_inputs: np.ndarray | None = None

    def __post_init__(self):
        read_only(self)

    @classmethod
    def build(cls, task: Task, options: dict[str, Any] | None = None) -> Plant:
        """The plant of `task` for the env options `options` (see `ENV_OPTIONS`; the rest
        are the model's parameters by name)."""
        if not isinstance(task, Task):
            raise TypeError(f"task must be an envs.Task, got {type(task).__name__}.")
        params, opts = split_options(options)
        system = compile_system(task.model, params)
        p = parameter_record(task, system)
        parts = _declared(task, system, p, opts.get("max_input"))
        declared = task.randomize if opts.get("randomize") is None else opts["randomize"]
        spec = None
        if declared is not False and declared is not None:
            spec = Randomization.declare(system, declared)
        context = observed(spec, opts.get("observe_params"))
        obs = compile_observation(
            task,
            system.n_q,
            parts["row_names"],
            parts["goal_names"],
            p,
            parts["limits"],
            (parts["goal_low"], parts["goal_high"]),
            context,
        )
        plant = cls(
            task=task,
            system=system,
            p=p,
            options=opts,
            observation=obs,
            randomize=spec,
            **parts,
            **stepping(task, opts),
        )
        checks.check_with_model(plant)
        facts = {"perturb": Perturbations.parse(opts.get("perturb"), plant)}
        if spec is not None:  # the supports compared here, where plants are built
            base = {k: v for k, v in opts.items() if k not in ("observe_params", "perturb")}
            base.update(params, randomize=False)
            follows = nominal.warn(plant, lambda values: cls.build(task, {**base, **values}))
            facts["follows"] = follows
            if follows and task.constants is not None:
                facts["constant_inputs"] = nominal.constant_inputs(plant)
        return dataclasses.replace(plant, **facts)

    # ---- the compiled observation ----------------------------------------------------------
    @property
    def ops(self) -> np.ndarray:
        """int64 (n_cols, 4): the observation's column operations (envs.observation)."""
        return self.observation.ops

    @property
    def derived(self) -> tuple:
        return self.observation.derived

    @property
    def context(self) -> np.ndarray:
        """int64 (k, 2): observation column, parameter column of each observed parameter."""
        return self.observation.context

    @property
    def obs_low(self) -> np.ndarray:
        return self.observation.low

    @property
    def obs_high(self) -> np.ndarray:
        return self.observation.high

    @property
    def columns(self) -> tuple:
        """(label, low, high, unit) of each observation column."""
        return self.observation.columns

    @property
    def periodic(self) -> np.ndarray:
        return self.observation.periodic

    @property
    def unobserved(self) -> tuple[str, ...]:
        return self.observation.unobserved

    @property
    def obs_size(self) -> int:
        return self.observation.size

    # ---- inputs and rewards ----------------------------------------------------------------
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
        return observation.state_from_observation(
            self.observation, self.system, len(self.state_names), obs
        )

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
        return observation.goal_from_observation(
            self.observation, self.task, len(self.goal_names), obs
        )

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
        if callable(op):  # either form (envs.names.operating_state)
            return call_operating_point(op, self, g, x)
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

    # ---- starting states (envs.starts) ------------------------------------------------------
    def sample_start(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """One starting state and goal from the task's start distribution (checked)."""
        return starts.sample_start(self, rng)

    def sample_states(self, k: int) -> np.ndarray:
        """k starting states (a fixed seed), for checks."""
        return starts.sample_rows(self, k, outputs=False)[0]

    def sample_rows(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """k rows the task functions see (starting states and their outputs) and goals."""
        return starts.sample_rows(self, k, outputs=True)

    def check_goal(self, g: np.ndarray) -> None:
        """ValueError unless every goal component lies in its declared range."""
        starts.check_goal(self, g)

    def start_rows(
        self, rngs, options: dict | None, rows: list[int], batch: int | None, params=None
    ):
        """Starting states and goals of `rows` (see `envs.starts.start_rows`)."""
        return starts.start_rows(self, rngs, options, rows, batch, params)


def _declared(task: Task, system, p, max_input) -> dict:
    """The plant's names, input limits, state limits, goal ranges and reward bounds,
    resolved at the record p and checked against the model."""
    names = state_names(system)
    for name in task.outputs:
        if name not in system.output_names:
            raise ValueError(
                f"Task {task.name!r} asks for output {name!r}; {system.name} has "
                f"{', '.join(system.output_names) or 'none'}."
            )
    row_names = names + tuple(task.outputs)
    for name in task.actuated:
        if name not in system.inputs:
            raise ValueError(
                f"Task {task.name!r} actuates {name!r}; {system.name}'s inputs are "
                f"{', '.join(system.inputs) or 'none'}."
            )
    actuated = np.array([system.inputs.index(k) for k in task.actuated], dtype=np.int64)
    low, high = input_limits(task.max_input if max_input is None else max_input, p, len(actuated))
    limits = np.full(2 * system.n_q, np.inf)
    for name, bound in task.limits.items():
        limits[index_of(task, names, name, "limits")] = resolve(bound, p)
    for name in task.start if isinstance(task.start, dict) else ():
        index_of(task, names, name, "start")
    goal_names = tuple(g.name for g in task.goal)
    clash = set(goal_names) & set(p.dtype.names)
    if clash:
        raise checks.DeclarationError(
            f"Task {task.name!r}: goal names {sorted(clash)} are also parameter names."
        )
    clash = set(goal_names) & set(row_names)
    if clash:
        raise ValueError(f"Task {task.name!r}: goal names {sorted(clash)} are also state names.")
    return {
        "state_names": names,
        "row_names": row_names,
        "output_index": np.array(
            [system.output_names.index(k) for k in task.outputs], dtype=np.int64
        ),
        "actuated": actuated,
        "input_low": low,
        "input_high": high,
        "limits": limits,
        "goal_names": goal_names,
        "goal_low": np.array([resolve(g.low, p) for g in task.goal]),
        "goal_high": np.array([resolve(g.high, p) for g in task.goal]),
        "term_low": np.array([resolve(t.low, p) for t in task.terms]),
        "term_high": np.array([resolve(t.high, p) for t in task.terms]),
    }


__all__ = ["ENV_OPTIONS", "Plant", "state_names"]
