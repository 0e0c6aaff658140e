"""What the single and the vector env share: the runtime of a bound plant built from the
env's keyword arguments, and the contract agents read (plant, system, state, goal,
operating point, inverse maps, action scaling), each delegated to the plant or read from
the runtime. The episodes' operations (`start`, `begin`, `redraw`) are the runtime's."""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from .checks import checked_rows, positive_float, positive_int, real_array
from .plant import Plant
from .runtime import Runtime
from .step import wait_for_background
from .task import Task

GOALS_REMEMBERED = 4096
"""Operating points an env keeps, one per distinct goal (`ContractMixin.operating_point`)."""


def make_runtime(task: Task, n: int, options: dict[str, Any]) -> Runtime:
    """A runtime of `n` rows of `task`'s plant (`Plant.build(task, options)`: the env
    options of `envs.plant.ENV_OPTIONS` and the model's parameters by name).

    One thread by default: on a shared machine (two cores, other processes busy) a second
    thread waits a scheduler timeslice for a core at every step, measured 0.12x the speed
    of one thread at N = 1024 and 0.7x at 16384 (benchmarks/env_speed.py). Give
    `num_threads=available_cores()` where the cores are yours.

    A fused step still compiling in the background (`envs.step.Step`) is waited
    for first: numba swaps the process's warning filters while it compiles (they are not
    per thread before Python 3.14), and a plant's build warns (its nominal values, a task
    function left as Python)."""
    wait_for_background()
    return Runtime(Plant.build(task, options), n, perturbed=True)


def available_cores() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def horizon(env, task: Task) -> int:
    """Steps to the time limit the early-end penalty counts: the limit of this env's own
    spec (`gymnasium.make(id, max_episode_steps=N)` sets it), else the task's
    `max_episode_steps`."""
    spec = getattr(env, "spec", None)
    steps = getattr(spec, "max_episode_steps", None)
    return int(task.max_episode_steps if steps is None else steps)


class ContractMixin:
    """The contract of a Lagrange env over its runtime `self._rt` (single: row 0)."""

    _rt: Runtime
    _single: bool

    @property
    def plant(self) -> Plant:
        """The bound plant: the task on its compiled model with this env's parameters."""
        return self._rt.plant

    @property
    def task(self) -> Task:
        return self._rt.plant.task

    @property
    def system(self):
        """The compiled `dynamics.System`."""
        return self._rt.system

    @property
    def control_period(self) -> float:
        return self._rt.plant.control_period

    @property
    def substeps(self) -> int:
        return self._rt.plant.substeps

    @property
    def integrator(self) -> str:
        """The fixed-step method of the `substeps` per control period: "rk4" or "dop853"."""
        return self._rt.plant.integrator

    @property
    def max_input(self) -> np.ndarray:
        """Largest magnitude of each actuated input (N*m or N); see `plant.input_low`,
        `plant.input_high` for asymmetric limits."""
        return self._rt.plant.max_input

    @property
    def periodic(self) -> tuple[bool, ...]:
        """True for the coordinates observed as angles."""
        return tuple(bool(v) for v in self._rt.plant.periodic)

    @property
    def state(self) -> np.ndarray:
        """Physical state x = [q, qdot] (copy): (2n,) single, (N, 2n) vector."""
        return self._rt.X[0].copy() if self._single else self._rt.X.copy()

    @property
    def goal(self) -> np.ndarray:
        """The goal or command (copy): (n_g,) single, (N, n_g) vector."""
        return self._rt.G[0].copy() if self._single else self._rt.G.copy()

    @property
    def time(self) -> np.ndarray | float:
        """Time since reset, s: float single, (N,) vector."""
        return float(self._rt.T[0]) if self._single else self._rt.T.copy()

    def simulator(self, n: int) -> Runtime:
        """A runtime of `n` rows of this env's plant (`reset_rows`, `step`): the env's own
        step, integrator and task, for agents that simulate closed loops."""
        return Runtime(self._rt.plant, n)

    def action_to_input(self, action) -> np.ndarray:
        """Model input vector u for `action` (clipped to [-1, 1]); batched over leading axes."""
        return self._rt.plant.action_to_input(action)

    def input_to_action(self, u) -> np.ndarray:
        """The action that applies model input u (unclipped inverse of `action_to_input`)."""
        return self._rt.plant.input_to_action(u)

    def _batched(self, fn, obs, size: int) -> np.ndarray:
        obs = real_array(obs, "observation")
        rows = obs.reshape(-1, obs.shape[-1])
        return fn(rows).reshape(obs.shape[:-1] + (size,))

    def state_from_observation(self, obs) -> np.ndarray:
        """Physical states recovered from observations (batched over leading axes)."""
        return self._batched(self._rt.plant.state_from_observation, obs, self.system.state_size)

    def goal_from_observation(self, obs) -> np.ndarray:
        """The goals encoded in observations (batched over leading axes)."""
        plant = self._rt.plant
        return self._batched(plant.goal_from_observation, obs, len(plant.goal_names))

    def operating_point(self, obs=None) -> tuple[np.ndarray, np.ndarray]:
        """(x0, u0): the state and model inputs the task regulates to, for the current
        goals or for those encoded in `obs` (batched like obs)."""
        plant = self._rt.plant
        if obs is None:
            g, x = self._rt.G, self._rt.X
            lead: tuple[int, ...] = () if self._single else (self._rt.n,)
        else:
            o = real_array(obs, "observation")
            lead = o.shape[:-1]
            rows = o.reshape(-1, o.shape[-1])
            g, x = plant.goal_from_observation(rows), plant.state_from_observation(rows)
        if callable(plant.task.operating_point):  # it may read the state
            x0, u0 = plant.operating_point(g, x)
        else:
            x0, u0 = self._operating_point_of_goals(np.atleast_2d(g), np.atleast_2d(x))
        return x0.reshape(lead + x0.shape[-1:]), u0.reshape(lead + u0.shape[-1:])

    def _operating_point_of_goals(self, g: np.ndarray, x: np.ndarray):
        """`Plant.operating_point` of goal rows g, each distinct goal solved once per env:
        a declared (dict) operating point depends on the goals alone, and the plant never
        changes, while agents ask at every step (the hand-over, for each row)."""
        memo = self.__dict__.setdefault("_operating_points", {})
        x0 = np.empty((len(g), self.system.state_size))
        u0 = np.empty((len(g), self.system.n_u))
        for i in range(len(g)):
            key = g[i].tobytes()
            point = memo.get(key)
            if point is None:
                if len(memo) >= GOALS_REMEMBERED:
                    memo.clear()
                point = memo[key] = self._rt.plant.operating_point(g[i : i + 1], x[i : i + 1])
            x0[i], u0[i] = point[0][0], point[1][0]
        return x0, u0


__all__ = [
    "ContractMixin",
    "available_cores",
    "checked_rows",
    "horizon",
    "make_runtime",
    "positive_float",
    "positive_int",
    "real_array",
]
