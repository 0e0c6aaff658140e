"""A task, declared once as data plus plain functions.

A `Task` names what an environment is about: the model it runs on, the inputs the action
drives, the observation (features with units and bounds), the goal or command, the reward
terms with their bounds, success and failure, the start distribution, and what agents need
(operating point, LQR weights and region, a heuristic, training hyperparameters). From it
the runtime builds the observation map, `observation_space`, the inverse maps (observation
-> state and goal) and the env docstring's tables.

Task functions are plain vectorised numpy over rows, all with one signature::

    def reward(x, a, g, p):  # -> one (N,) array per reward term, in declared order
    def success(x, a, g, p):  # -> (N,) bool
    def failure(x, a, g, p):  # -> (N,) bool: the episode terminates (with the penalty)

x: (N, 2n + k) rows of the state [q, qdot] followed by the task's declared model outputs;
a: (N, n_a) clipped actions in [-1, 1]; g: (N, n_g) goals; p: the parameters, read by
name (`p.m1`, `p.radius`): the model's parameters and the task's `constants`. The runtime
compiles them with numba when it can (use `dynamics.wrap` for angles) and otherwise calls
them as they are. Any number in a declaration (a bound, a limit, a range) may instead name a
parameter or constant of p ("rod_length") or be a function of p, resolved once when the env
is built.
"""

from __future__ import annotations

import textwrap
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

Number = float | str | Callable[[Any], float]
"""A number, the name of a parameter or constant of p, or a function of p giving one."""


def resolve(value, p) -> float:
    """A declared number: `value`, `p.<value>` for a name, or `value(p)` for a function."""
    if isinstance(value, str):
        try:
            return float(getattr(p, value))
        except AttributeError:
            known = ", ".join(p.dtype.names)
            raise ValueError(f"{value!r} names no parameter or constant; known: {known}.") from None
    return float(value(p) if callable(value) else value)


# ---- observation features ----------------------------------------------------------------
@dataclass(frozen=True)
class Angle:
    """cos and sin of an angle: a coordinate, or a goal component (two columns in [-1, 1])."""

    name: str


@dataclass(frozen=True)
class AngleError:
    """cos and sin of the wrapped difference `name - goal` (an angle and its goal angle)."""

    name: str
    goal: str


@dataclass(frozen=True)
class Value:
    """A state component, model output or goal component as it is; its bound comes from
    the task's `limits` (state), the goal's range (goal) or `bound` (given here)."""

    name: str
    bound: Number | None = None
    unit: str = ""


@dataclass(frozen=True)
class Derived:
    """A feature computed by `fn(x, a, g, p) -> (N,)`, observed within [low, high]."""

    name: str
    fn: Callable
    low: Number
    high: Number
    unit: str = ""


Feature = Angle | AngleError | Value | Derived


# ---- goal, reward terms, agents ----------------------------------------------------------
@dataclass(frozen=True)
class Goal:
    """One component of the goal or command: drawn uniformly in [low, high] unless the
    task's `start` draws it; `low == high` makes it fixed (and needs no observation)."""

    name: str
    unit: str
    low: Number
    high: Number
    angle: bool = False
    doc: str = ""


@dataclass(frozen=True)
class Term:
    """A reward term and its bounds: the runtime clips the term into [low, high], so the
    bounds hold by construction (they decide the early-end penalty, see `Task`)."""

    name: str
    low: Number
    high: Number
    doc: str = ""


@dataclass(frozen=True)
class LQRHints:
    """What LQR needs beyond the operating point.

    states: the state components it regulates (None: all of [q, qdot]).
    scales: Bryson's rule, Q = diag(1 / scale^2): the error in each kept component that
        costs as much as a full-scale action (absent names: `default_scale`).
    R: weight of the normalised action; scalar or one per action component.
    region: half-widths of the uniform perturbations of the operating point from which LQR
        is expected to succeed (absent components: half their scale; None: all of them).
    """

    states: tuple[str, ...] | None = None
    scales: Mapping[str, float] = field(default_factory=dict)
    default_scale: float = 1.0
    R: float | tuple[float, ...] = 1.0
    region: Mapping[str, float] | None = None


@dataclass(frozen=True)
class Heuristic:
    """A model-based baseline: `target` is 'module:Class', built as Class(env, **kwargs)."""

    description: str
    target: str
    kwargs: Mapping[str, Any] = field(default_factory=dict)


# ---- the declaration ---------------------------------------------------------------------
@dataclass(frozen=True)
class Task:
    """Everything particular to one task.

    model: a registered model name, a `dynamics.Model`, a `ModelSpec` factory or a
        compiled `dynamics.System`.
    actuated: names of the model inputs the action drives, in action order.
    max_input: the physical limit of each actuated input (N*m or N), action 1 maps to it
        (numbers, or one function of p giving them all).
    observation: the features, in order (see `Angle`, `AngleError`, `Value`, `Derived`).
    reward, terms: the reward function and its `Term`s, in the order it returns them.
    success: the task's success criterion (reported as info["is_success"]).
    failure: states that end the episode as failed (terminated), or None.
    goal: the goal's components (`Goal`); () for a task without one.
    start: uniform half-ranges {state name: (low, high)} (others 0; goals uniform over
        their ranges), or a function (rng, p) -> (x, g) for one row.
    limits: {state name: bound on |value|}; beyond it, or non-finite, the run diverged.
    outputs: model outputs appended to the rows x the task functions see.
    constants: function of the compiled System -> {name: float}, added to p.
    operating_point: what the task regulates to: {coordinate: number or goal name}
        (rates 0, other coordinates 0), or a function (g, x, system) -> x0 rows.
    lqr, heuristic, algo, hyperparams: what agents use (hyperparams by algorithm name,
        in the format of agents/hyperparams/<algo>.yml).
    draw: draw(surface, x, g, p, history) renders one frame from one row x (the state and
        the declared outputs) and goal g; history: the rows of the frames rendered so far
        this episode, or None (default: a dial per angle, a slider per other coordinate).

    Ending early never pays: a step that fails or diverges terminates, and its reward is
    the step's own plus (steps left to the time limit) x min(0, lowest possible reward),
    the worst the rest of the episode could have paid. Tasks whose terms are bounded
    below by 0 pay no penalty.
    """

    name: str
    model: Any
    actuated: tuple[str, ...]
    max_input: tuple[Number, ...] | Callable
    observation: tuple[Feature, ...]
    reward: Callable
    terms: tuple[Term, ...]
    success: Callable
    failure: Callable | None = None
    goal: tuple[Goal, ...] = ()
    start: Mapping[str, tuple[Number, Number]] | Callable = field(default_factory=dict)
    limits: Mapping[str, Number] = field(default_factory=dict)
    outputs: tuple[str, ...] = ()
    constants: Callable | None = None
    operating_point: Mapping[str, Any] | Callable | None = None
    control_period: float = 0.05
    substeps: int = 10
    integrator: str = "rk4"  # "rk4" or "dop853" (dynamics.methods), `substeps` of it
    max_episode_steps: int = 200
    lqr: LQRHints = field(default_factory=LQRHints)
    heuristic: Heuristic | None = None
    algo: str = "ppo"
    hyperparams: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    draw: Callable | None = None

    def __post_init__(self):
        if not self.actuated:
            raise ValueError(f"Task {self.name!r}: `actuated` names no input.")
        if not callable(self.max_input) and len(self.max_input) != len(self.actuated):
            raise ValueError(
                f"Task {self.name!r}: {len(self.max_input)} max_input values for "
                f"{len(self.actuated)} actuated inputs {self.actuated}."
            )
        names = [t.name for t in self.terms]
        if not names or len(set(names)) != len(names):
            raise ValueError(f"Task {self.name!r}: reward terms must be named once each: {names}.")
        goals = [g.name for g in self.goal]
        if len(set(goals)) != len(goals):
            raise ValueError(f"Task {self.name!r}: repeated goal component in {goals}.")

    # ---- documentation -------------------------------------------------------------------
    def describe(self, **params) -> str:
        """The action, observation and reward-term tables (Markdown) at these model
        parameters (defaults otherwise): what the env docstring shows."""
        from .layout import build_layout

        return self.tables(build_layout(self, params))

    def tables(self, layout) -> str:
        """The '## Action Space' and '## Observation Space' sections of the env docstring,
        for a built `layout` (see `envs.layout.Layout`)."""
        prose = (
            f"`Box(-1, 1, ({len(self.actuated)},), float32)`; action 1 is the input's limit "
            "(`max_input`, overridable when the env is made). Actions outside [-1, 1] are "
            "clipped; NaN or inf actions raise ValueError, complex ones TypeError."
        )
        lines = [
            "## Action Space",
            *textwrap.wrap(prose, 88),
            "",
            "| Num | Input | Limit |",
            "|-----|-------|-------|",
        ]
        for i, (name, limit) in enumerate(zip(self.actuated, layout.max_input)):
            lines.append(f"| {i} | {name} | {limit:.4g} |")
        lines += [
            "",
            "## Observation Space",
            f"`Box(low, high, ({layout.obs_size},), float32)`:",
            "",
            "| Num | Observation | Min | Max | Unit |",
            "|-----|-------------|-----|-----|------|",
        ]
        for i, (label, lo, hi, unit) in enumerate(layout.columns):
            lines.append(f"| {i} | {label} | {lo:.4g} | {hi:.4g} | {unit} |")
        lines += ["", "## Reward terms", "", "| Term | Min | Max | Meaning |", "|---|---|---|---|"]
        for term, lo, hi in zip(self.terms, layout.term_low, layout.term_high):
            lines.append(f"| {term.name} | {lo:.4g} | {hi:.4g} | {term.doc} |")
        return "\n".join(lines)


def document(doc: str, task: Task, **params) -> str:
    """`doc` (a Gymnasium-style env docstring) with the generated action, observation and
    reward-term tables of `task` (at its default parameters) put between its
    '## Description' and '## Rewards' sections, replacing earlier generated ones."""
    tables = task.describe(**params)
    head, sep, tail = doc.partition("## Rewards\n")
    if not sep:
        return doc.rstrip() + "\n\n" + tables + "\n"
    head = head.split("## Action Space\n")[0].rstrip() + "\n\n"
    return head + tables + "\n\n" + sep + tail


__all__ = [
    "Angle",
    "AngleError",
    "Derived",
    "Feature",
    "Goal",
    "Heuristic",
    "LQRHints",
    "Task",
    "Term",
    "Value",
    "document",
    "resolve",
]
