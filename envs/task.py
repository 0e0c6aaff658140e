"""A task, declared once as data plus plain functions.

A `Task` names what an environment is about: the model it runs on, the inputs the action
drives, the observation (features with units and bounds), the goal or command, the reward
terms with their bounds and functions, success and failure, the start distribution, and
what agents need (operating point, LQR weights and region, a heuristic, training
hyperparameters). From it the plant (`envs.plant`) builds the observation map,
`observation_space`, the inverse maps (observation -> state and goal) and the env
docstring's tables (`envs.docs`).

Task functions are plain vectorised numpy over rows, and read their inputs by name::

    def angle(x, a, goal, p):  # a reward term: Term("angle", low, high, fn=angle)
        return -wrap(x.theta1 - goal.theta1_star) ** 2
    def success(x, a, goal, p):  # -> (N,) bool
    def failure(x, a, goal, p):  # -> (N,) bool: the episode terminates (with the penalty)

x: the rows' state components by name (coordinates, their rates `<name>_dot`, then the
task's declared model outputs); a: the clipped actions in [-1, 1] by actuated input;
goal: the goal components (`*` in a name reads `_star`); each an (N,) array. p: the model's
parameters and the task's `constants` (`p.m1`, `p.g`). See `envs.names`. The inputs are
read-only: compute new arrays. Each function runs once as numpy on sample rows when the env
is made (`envs.checks.trial_run`: shapes, booleans, finiteness, index slips name the
function); the runtime then compiles it with numba, bounds-checked, when it can (use
`dynamics.wrap` for angles), and otherwise calls it as it is.

Any number in a declaration (a bound, a limit, a range) may instead name a parameter or
constant of p ("rod_length") or be a function of p, resolved once when the env is built.

The former form, one `reward(x, a, g, p)` returning every term in order with x, a, g 2-D
arrays read by column number, was removed: giving `reward` is an error that shows the
named form.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from .checks import DeclarationError
from .distributions import distribution
from .task_checks import check_task

FORMER_FORM = (
    "Task {name!r}: `reward=` (one function returning every term, reading columns by "
    "number) was removed; give each Term its own function, which reads its inputs by name: "
    "`Term('upright', -1.0, 1.0, fn=upright)` with `def upright(x, a, goal, p): return "
    "np.cos(x.theta)` (see envs.task)."
)
"""The error of a task declared the former way."""

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
    """A reward term, its bounds and its function `fn(x, a, goal, p) -> (N,)`: the runtime
    clips the term into [low, high], so the bounds hold by construction (they decide the
    early-end penalty, see `Task`). Finite bounds only."""

    name: str
    low: Number
    high: Number
    doc: str = ""
    fn: Callable | None = None


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
    terms: the reward's `Term`s, each with its function (the reward is their sum).
    reward: removed (the former one-function form); given, it is an error that shows the
        named form.
    success: the task's success criterion (reported as info["is_success"]).
    failure: states that end the episode as failed (terminated), or None.
    goal: the goal's components (`Goal`); () for a task without one.
    start: uniform half-ranges {state name: (low, high)} (others 0; goals uniform over
        their ranges), or a function (rng, p) -> ({state: value}, {goal: value}) for one
        row (states left out 0, goals left out uniform; see `envs.names`).
    limits: {state name: bound on |value|}; beyond it, or non-finite, the run diverged.
    outputs: model outputs appended to the rows x the task functions see.
    constants: function of the compiled System -> {name: float}, added to p.
    operating_point: what the task regulates to: {coordinate: number or goal name}
        (rates 0, other coordinates 0), or a function (x, goal, p) -> {state: value or
        (N,) array} of all rows (others 0; `(x, goal, p, system)` to get the compiled
        model; see `envs.names`). Both functions are tried when the env is made.
    lqr, heuristic, algo, hyperparams: what agents use (hyperparams by algorithm name,
        in the format of agents/learning/hyperparams/<algo>.yml).
    randomize: the model parameters each copy draws by default (the forms of the env
        option `randomize=`, see `envs.randomize`), or None; the env option replaces it,
        `randomize=False` turns it off.
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
    reward: Callable | None = None
    terms: tuple[Term, ...] = ()
    success: Callable | None = None
    failure: Callable | None = None
    goal: tuple[Goal, ...] = ()
    start: Mapping[str, tuple[Number, Number]] | Callable = field(default_factory=dict)
    limits: Mapping[str, Number] = field(default_factory=dict)
    outputs: tuple[str, ...] = ()
    constants: Callable | None = None
    operating_point: Mapping[str, Any] | Callable | None = None
    control_period: float = 0.05
    substeps: int = 10
    integrator: str = "dop853"  # "dop853" or "rk4" (dynamics.methods), `substeps` of it
    max_episode_steps: int = 200
    lqr: LQRHints = field(default_factory=LQRHints)
    heuristic: Heuristic | None = None
    algo: str = "ppo"
    hyperparams: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    draw: Callable | None = None
    randomize: Mapping[str, Any] | None = None

    def __post_init__(self):
        if self.reward is not None:
            raise DeclarationError(FORMER_FORM.format(name=self.name))
        check_task(self, (Angle, AngleError, Value, Derived), Goal, Term, LQRHints, Heuristic)
        if self.randomize is not None:  # the forms checked here, the names on the model
            if not isinstance(self.randomize, Mapping):
                raise DeclarationError(
                    f"Task {self.name!r}: `randomize` must be a dict {{parameter: (low, high) "
                    f"or a distribution}}, got {type(self.randomize).__name__}."
                )
            for key, form in self.randomize.items():
                try:
                    distribution(form, key)
                except ValueError as exc:
                    raise DeclarationError(f"Task {self.name!r}: {exc}") from None


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
    "resolve",
]
