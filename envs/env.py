"""`LagrangianEnv`: one copy of a task, a thin Gymnasium wrapper around a runtime of one row."""

from __future__ import annotations

import sys
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from . import rendering
from .contract import ContractMixin, horizon, make_runtime, real_array
from .runtime import NonFiniteActions
from .task import Task


class LagrangianEnv(ContractMixin, gym.Env):
    """A Gymnasium env of any `envs.Task` (its docstring documents the task).

    `LagrangianEnv(task, render_mode=None, control_period=None, substeps=None,
    max_input=None, **model_parameters)`: the task's defaults unless given. Registering a
    task is one call::

        gymnasium.register("MyNS/CartPole-v0", entry_point="envs:LagrangianEnv",
                           vector_entry_point="envs:LagrangianVectorEnv",
                           kwargs={"task": TASK}, max_episode_steps=TASK.max_episode_steps)

    `info` carries the physical state, the applied model inputs, the energy, the reward
    terms (clipped into their bounds), `is_success`, `diverged`, for constrained
    models the constraint residual, with `randomize=`, the model parameters in force
    (`params`) and, with pushes (`perturb=`, see `envs.perturb`), the force of the push
    acting over the last step (`push`, N; zeros when none).
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["human", "rgb_array"]}
    _single = True

    def __init__(self, task: Task, render_mode: str | None = None, **options: Any):
        self._rt = make_runtime(task, 1, options)
        plant = self._rt.plant
        fps = max(1, round(min(1.0 / self._rt.control_period, 1000.0)))  # frames/s, capped
        self.metadata = {**type(self).metadata, "render_fps": fps}
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode must be one of {self.metadata['render_modes']} or None, "
                f"got {render_mode!r}."
            )
        self.render_mode = render_mode
        self.action_space = spaces.Box(-1.0, 1.0, (len(plant.actuated),), np.float32)
        self._action_shape = self.action_space.shape
        self.observation_space = spaces.Box(
            plant.obs_low.astype(np.float32), plant.obs_high.astype(np.float32), dtype=np.float32
        )
        self._ready = False
        self._horizon: int | None = None
        self._viewer: rendering.Viewer | None = None
        self._history: list[np.ndarray] = []

    def __repr__(self) -> str:
        return f"<LagrangianEnv {self.task.name} on {self.system.name}>"

    # ---- Gymnasium API ---------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        if self._horizon is None:  # the episode limit the early-end penalty counts
            self._horizon = enclosing_time_limit(self)
        whole = isinstance(seed, (int, np.integer)) and not isinstance(seed, bool)
        if seed is not None and not whole:
            raise ValueError(f"seed must be an int or None, got {seed!r:.80}.")
        before = self._np_random, self._np_random_seed
        state = None if self._np_random is None else self._np_random.bit_generator.state
        super().reset(seed=None if seed is None else int(seed))
        try:
            x, g, drawn = self._rt.start([self.np_random], options, [0], None, seed is not None)
        except (TypeError, ValueError):  # refused options leave the generator as it was
            self._np_random, self._np_random_seed = before
            if state is not None:
                self._np_random.bit_generator.state = state
            raise
        self._rt.begin([0], x, g, drawn, [self.np_random])
        self._ready = True
        self._history = []
        if self.render_mode == "human":
            self.render()
        return self._rt.O[0].copy(), self._info(reset=True)

    def step(self, action):
        if not self._ready:
            raise RuntimeError("Call reset() before step().")
        # native float32 and float64 arrays go to the runtime as they are (it gives its
        # compiled step float64, float32's values exactly)
        if type(action) is np.ndarray and action.dtype.char in "fd" and action.dtype.isnative:
            a = action
        else:
            a = real_array(action, "action")
        if a.shape != self._action_shape:
            raise ValueError(f"Expected action of shape {self._action_shape}, got {a.shape}.")
        rt = self._rt
        if self._horizon is None:  # no TimeLimit around it: the task's own limit
            self._horizon = horizon(self, self.task)
        try:  # the runtime checks finiteness before it changes anything
            diverged = rt.step(a.reshape(1, -1), self._horizon)
        except NonFiniteActions:
            raise ValueError(f"Action contains NaN or inf: {action!r}.") from None
        rt.redraw([self.np_random])  # parameters declared to change every k steps
        info = self._info(diverged=diverged)
        if self.render_mode == "human":
            self.render()
        return rt.O[0].copy(), rt.R.item(0), rt.terminated.item(0), False, info

    def _info(self, reset: bool = False, diverged: bool = False) -> dict[str, Any]:
        rt = self._rt
        info: dict[str, Any] = {
            "state": rt.X[0].copy(),
            "input": rt.U[0].copy(),
            "energy": rt.energy_of_row0(),
        }
        if reset:
            info["goal"] = rt.G[0].copy()
        else:
            info["reward_terms"] = rt.reward_terms(0)
            info["is_success"] = rt.success.item(0)
            info["diverged"] = diverged
        if self.system.n_c:
            info["constraint_residual"] = rt.constraint_residual()[0]
        if rt.per_row:  # randomised: the model parameters this copy steps with
            info["params"] = rt.params(0)
        if rt.perturber is not None and rt.perturber.spec.push is not None:
            info["push"] = rt.perturber.force[0].copy()  # the push of the last step, N
        return info

    # ---- rendering -------------------------------------------------------------------------
    def render(self):
        if self.render_mode is None:
            gym.logger.warn(
                "render() was called without a render_mode; pass render_mode='rgb_array' "
                "or 'human' to gymnasium.make."
            )
            return None
        if self._viewer is None:
            self._viewer = rendering.Viewer(self.render_mode, self.metadata["render_fps"])
        x, g = self._rt.rows()[0].copy(), self._rt.G[0].copy()
        self._history.append(x)
        return self._viewer.show(lambda surface: draw(self, surface, x, g, self._history))

    def close(self):
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None

    def __getstate__(self):
        state = self.__dict__.copy()
        state["_viewer"] = None  # a pygame window does not travel
        return state


def enclosing_time_limit(env: gym.Env, depth: int = 12) -> int | None:
    """The limit of the TimeLimit wrapper whose reset or step is calling into `env` (the
    one `gymnasium.make` put around it, with `make(id, max_episode_steps=N)` or the
    registered limit), or None. Gymnasium tells a wrapped env nothing of its wrappers, and
    `make_vec`'s native entry point takes no additional wrapper that could, so the calling
    frames are asked, once per env."""
    frame = sys._getframe(1)
    for _ in range(depth):
        frame = frame.f_back
        if frame is None:
            return None
        caller = frame.f_locals.get("self")
        if isinstance(caller, gym.wrappers.TimeLimit) and caller.unwrapped is env:
            return int(caller._max_episode_steps)
    return None


def draw(env, surface, x, g, history) -> None:
    """One frame: the task's `draw`, or the generic dials and sliders."""
    task = env.task
    if task.draw is not None:
        task.draw(surface, x, g, env.plant.p, history)
    else:
        rendering.draw_generic(surface, x, env.plant)
