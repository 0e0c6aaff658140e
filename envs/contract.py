"""What the single and the vector env share: building the runtime from keyword arguments,
checking what users hand in, and the contract agents read (system, state, goal, operating
point, inverse maps, action scaling)."""

from __future__ import annotations

import math
import os
from typing import Any

import gymnasium as gym
import numpy as np

from dynamics.system import method_tableau

from .layout import Layout, build_layout
from .runtime import Runtime
from .task import Task


def make_runtime(task: Task, n: int, options: dict[str, Any]) -> Runtime:
    """A runtime of `n` rows of `task`; `options`: control_period, substeps, integrator
    ("rk4" or "dop853"), num_threads (threads stepping the rows, default 1; results are the
    same for any count), max_input and the model's parameters by name.

    One thread by default: on a shared machine (two cores, other processes busy) a second
    thread waits a scheduler timeslice for a core at every step, measured 0.12x the speed
    of one thread at N = 1024 and 0.7x at 16384 (benchmarks/envs.py). Give
    `num_threads=available_cores()` where the cores are yours."""
    if not isinstance(task, Task):
        raise TypeError(f"task must be an envs.Task, got {type(task).__name__}.")
    options = dict(options)
    period = options.pop("control_period", None)
    substeps = options.pop("substeps", None)
    integrator = options.pop("integrator", None)
    threads = options.pop("num_threads", None)
    max_input = options.pop("max_input", None)
    layout = build_layout(task, options, max_input)
    period = positive_float("control_period", task.control_period if period is None else period)
    substeps = positive_int("substeps", task.substeps if substeps is None else substeps)
    integrator = task.integrator if integrator is None else integrator
    method_tableau(integrator)  # ValueError naming the known integrators
    threads = 1 if threads is None else positive_int("num_threads", threads)
    return Runtime(layout, n, period, substeps, integrator, threads)


def available_cores() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def horizon(env, task: Task) -> int:
    """Steps to the time limit the early-end penalty counts: the registered limit of the
    env's id, else the task's `max_episode_steps`."""
    spec = getattr(env, "spec", None)
    if spec is not None and spec.id in gym.registry:
        steps = gym.spec(spec.id).max_episode_steps
        if steps is not None:
            return int(steps)
    return int(task.max_episode_steps)


# ---- checking what users hand in ---------------------------------------------------------
def positive_float(name: str, value) -> float:
    if isinstance(value, (bool, str, bytes, complex, np.complexfloating)):
        raise TypeError(f"{name} must be a real number, got {value!r}.")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a number, got {value!r}.") from None
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}.")
    return v


def positive_int(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an integer, got {value!r}.")
    if value < 1:
        raise ValueError(f"{name} must be at least 1, got {value}.")
    return int(value)


def real_array(value, name: str) -> np.ndarray:
    """`value` as float64; TypeError for complex, object or non-numeric input."""
    a = np.asarray(value)
    kind = a.dtype.kind
    if kind == "f":
        return a.astype(np.float64, copy=False)
    if kind == "c":
        raise TypeError(f"{name} must be real, got complex values {value!r}.")
    if kind not in "biu":
        raise TypeError(f"{name} must be numeric, got dtype {a.dtype}.")
    return a.astype(np.float64)


def checked_rows(value, shape: tuple[int, ...], name: str, batch: int | None) -> np.ndarray:
    """`value` as rows of `shape`: one value (shared by every row when `batch` is given) or,
    for a vector env (`batch` rows), exactly `batch` rows; finite."""
    a = real_array(value, name)
    if batch is not None and a.shape == (batch,) + shape:
        rows = a
    elif a.shape == shape:
        rows = a[None] if batch is None else np.broadcast_to(a, (batch,) + shape)
    else:
        expected = (
            f"{shape}" if batch is None else f"{shape} or ({batch}, {', '.join(map(str, shape))})"
        )
        raise ValueError(f"Expected {name} of shape {expected}, got {a.shape}.")
    if not np.isfinite(rows).all():
        raise ValueError(f"{name} contains NaN or inf.")
    return np.array(rows, dtype=np.float64)


def start_rows(layout: Layout, rngs, options: dict | None, rows: list[int], batch: int | None):
    """Starting states and goals of `rows`: drawn from the task's start distribution with
    each row's generator, then replaced by options['state'] / options['goal'] if given
    (checked: shape, finite, state within the task's limits, goal within its ranges).
    Constrained models' states are projected onto their velocity constraints."""
    system = layout.system
    drawn = [layout.sample_start(rngs[i]) for i in rows]
    x = np.array([d[0] for d in drawn]).reshape(len(rows), system.state_size)
    g = np.array([d[1] for d in drawn]).reshape(len(rows), len(layout.goal_names))
    options = options or {}
    unknown = set(options) - {"state", "goal"}
    if unknown:
        raise ValueError(f"Unknown reset option(s) {sorted(unknown)}; known: 'state', 'goal'.")
    if options.get("state") is not None:
        given = checked_rows(options["state"], (system.state_size,), "options['state']", batch)
        x = given[rows]
        over = np.abs(x) > layout.limits
        if over.any():
            i = int(np.argwhere(over)[0][1])
            raise ValueError(
                f"options['state'] component {layout.state_names[i]!r} = "
                f"{x[over][0]:.6g} is beyond the task's limit {layout.limits[i]:.6g}."
            )
    if options.get("goal") is not None:
        given = checked_rows(options["goal"], (len(layout.goal_names),), "options['goal']", batch)
        g = given[rows]
        for row in g:
            layout.check_goal(row)
    if system.n_c:
        x = system.project(x)
    return x, g


class ContractMixin:
    """The contract of a Lagrange env over its runtime `self._rt` (single: row 0)."""

    _rt: Runtime
    _single: bool

    @property
    def task(self) -> Task:
        return self._rt.layout.task

    @property
    def layout(self) -> Layout:
        return self._rt.layout

    @property
    def system(self):
        """The compiled `dynamics.System`."""
        return self._rt.system

    @property
    def control_period(self) -> float:
        return self._rt.control_period

    @property
    def substeps(self) -> int:
        return self._rt.substeps

    @property
    def integrator(self) -> str:
        """The fixed-step method of the `substeps` per control period: "rk4" or "dop853"."""
        return self._rt.integrator

    @property
    def max_input(self) -> np.ndarray:
        """Physical limit of each actuated input (N*m or N): action 1 maps to it."""
        return self._rt.layout.max_input.copy()

    @property
    def periodic(self) -> tuple[bool, ...]:
        """True for the coordinates observed as angles."""
        return tuple(bool(v) for v in self._rt.layout.periodic)

    @property
    def state(self) -> np.ndarray:
        """Physical state x = [q, qdot] (copy): (2n,) single, (N, 2n) vector."""
        return self._rt.X[0].copy() if self._single else self._rt.X.copy()

    @property
    def goal(self) -> np.ndarray:
        """The goal or command (copy): (n_g,) single, (N, n_g) vector."""
        return self._rt.G[0].copy() if self._single else self._rt.G.copy()

    def action_to_input(self, action) -> np.ndarray:
        """Model input vector u for `action` (clipped to [-1, 1]); batched over leading axes."""
        a = np.clip(real_array(action, "action"), -1.0, 1.0)
        lay = self._rt.layout
        u = np.zeros(a.shape[:-1] + (self.system.n_u,))
        u[..., lay.actuated] = a * lay.max_input
        return u

    def input_to_action(self, u) -> np.ndarray:
        """The action that applies model input u (unclipped inverse of `action_to_input`)."""
        lay = self._rt.layout
        return real_array(u, "u")[..., lay.actuated] / lay.max_input

    def _batched(self, fn, obs, size: int) -> np.ndarray:
        obs = real_array(obs, "observation")
        rows = obs.reshape(-1, obs.shape[-1])
        return fn(rows).reshape(obs.shape[:-1] + (size,))

    def state_from_observation(self, obs) -> np.ndarray:
        """Physical states recovered from observations (batched over leading axes)."""
        return self._batched(self._rt.layout.state_from_observation, obs, self.system.state_size)

    def goal_from_observation(self, obs) -> np.ndarray:
        """The goals encoded in observations (batched over leading axes)."""
        lay = self._rt.layout
        return self._batched(lay.goal_from_observation, obs, len(lay.goal_names))

    def operating_point(self, obs=None) -> tuple[np.ndarray, np.ndarray]:
        """(x0, u0): the state and model inputs the task regulates to, for the current
        goals or for those encoded in `obs` (batched like obs)."""
        lay = self._rt.layout
        if obs is None:
            g, x = self._rt.G, self._rt.X
            lead: tuple[int, ...] = () if self._single else (self._rt.n,)
        else:
            o = real_array(obs, "observation")
            lead = o.shape[:-1]
            rows = o.reshape(-1, o.shape[-1])
            g, x = lay.goal_from_observation(rows), lay.state_from_observation(rows)
        x0 = lay.operating_state(g, x)
        u0 = operating_input(self, x0)
        return x0.reshape(lead + x0.shape[-1:]), u0.reshape(lead + u0.shape[-1:])


def operating_input(env, x0: np.ndarray) -> np.ndarray:
    """Inputs that hold x0 with zero accelerations: least squares over the actuated inputs
    (accelerations are affine in the inputs, so one evaluation per input gives the exact
    input matrix). Zero where no input is needed."""
    s, idx = env.system, list(env.layout.actuated)
    u = np.zeros(x0.shape[:-1] + (s.n_u,))
    a0 = s.accelerations(0.0, x0, u)
    cols = []
    for j in idx:
        e = u.copy()
        e[..., j] = 1.0
        cols.append(s.accelerations(0.0, x0, e) - a0)
    B = np.stack(cols, axis=-1)  # (..., n_q, n_a)
    u[..., idx] = -(np.linalg.pinv(B) @ a0[..., None])[..., 0]
    return u
