"""`LagrangianVectorEnv`: N copies of a task, a thin Gymnasium wrapper around a runtime of
N rows (one batched kernel call per step)."""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from . import rendering
from .contract import ContractMixin, make_runtime, positive_int, real_array
from .env import LagrangianEnv, draw
from .task import Task


class LagrangianVectorEnv(ContractMixin, VectorEnv):
    """`num_envs` copies of a task stepped together.

    `autoreset_mode`: Gymnasium's NEXT_STEP (default: a finished copy is reset by the
    following `step`, whose action it ignores, reward 0) or SAME_STEP (reset within the
    step that finished it; its last observation and info are in info['final_obs'] and
    info['final_info']). Copy i has its own generator, seeded `seed + i` as
    `SyncVectorEnv` seeds its envs, so it reproduces a single env reset with `seed + i` bit
    for bit. Episodes are truncated after `max_episode_steps` (from the registry) here.
    """

    metadata: ClassVar[dict[str, Any]] = {
        "render_modes": ["rgb_array"],
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }
    _single = False

    def __init__(
        self,
        task: Task,
        num_envs: int = 1,
        max_episode_steps: int | None = None,
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        **options: Any,
    ):
        self.num_envs = positive_int("num_envs", num_envs)
        self._rt = make_runtime(task, self.num_envs, options)
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"The vector env renders only 'rgb_array', got {render_mode!r}.")
        self.render_mode = render_mode
        self._done = np.zeros(self.num_envs, dtype=bool)
        self.metadata = dict(type(self).metadata)
        self.autoreset_mode = autoreset_mode
        self.max_episode_steps = (
            task.max_episode_steps
            if max_episode_steps is None
            else positive_int("max_episode_steps", max_episode_steps)
        )
        fps = max(1, round(min(1.0 / self._rt.control_period, 1000.0)))  # frames/s, capped
        self.metadata["render_fps"] = fps
        # the spaces of one copy are the single env's, built from the same plant
        plant = self._rt.plant
        one = gym.spaces.Box(
            plant.obs_low.astype(np.float32), plant.obs_high.astype(np.float32), dtype=np.float32
        )
        self.single_observation_space = one
        self.single_action_space = gym.spaces.Box(-1.0, 1.0, (len(plant.actuated),), np.float32)
        self.observation_space = batch_space(one, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._rngs = [seeding.np_random()[0] for _ in range(self.num_envs)]
        self._ready = False
        self._viewer = None

    @property
    def autoreset_mode(self) -> AutoresetMode:
        """NEXT_STEP or SAME_STEP (an AutoresetMode, its value or its name). Changed
        mid-run, copies that finished under NEXT_STEP still start afresh on the next step
        (so no copy steps on from its end), and `metadata` follows."""
        return self._autoreset_mode

    @autoreset_mode.setter
    def autoreset_mode(self, value) -> None:
        modes = (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP)
        mode = next((m for m in modes if value in (m, m.value, m.name)), None)
        if mode is None:
            raise ValueError(
                "autoreset_mode must be AutoresetMode.NEXT_STEP or SAME_STEP (or their names "
                f"'NEXT_STEP', 'SAME_STEP', or values 'NextStep', 'SameStep'), got {value!r}."
            )
        self._autoreset_mode = mode
        self.metadata["autoreset_mode"] = mode

    def reset(self, *, seed: int | list[int] | None = None, options: dict | None = None):
        rngs = self._rngs
        if seed is not None:
            rngs = [seeding.np_random(s)[0] for s in _seeds(seed, self.num_envs)]
        states = [r.bit_generator.state for r in rngs]
        rows = list(range(self.num_envs))
        try:
            x, g, drawn = self._rt.start(rngs, options, rows, self.num_envs, seed is not None)
        except (TypeError, ValueError):  # refused options leave the generators as they were
            for r, state in zip(rngs, states):
                r.bit_generator.state = state
            raise
        self._rngs = rngs
        self._rt.begin(rows, x, g, drawn, rngs)
        self._done[:] = False
        self._ready = True
        return self._rt.O.copy(), self._info(reset=True)

    def step(self, actions):
        if not self._ready:
            raise RuntimeError("Call reset() before step().")
        a = real_array(actions, "actions")
        if a.shape != self.action_space.shape:
            raise ValueError(f"Expected actions of shape {self.action_space.shape}, got {a.shape}.")
        if not np.isfinite(a).all():
            rows = np.flatnonzero(~np.isfinite(a).all(axis=1))
            raise ValueError(f"Actions contain NaN or inf (envs {rows.tolist()}).")
        rt = self._rt
        resetting = self._done.copy()  # NEXT_STEP: last step's finished copies start afresh
        rt.step(a, self.max_episode_steps)
        rt.redraw(self._rngs, ~resetting)  # every-k-steps parameters (not of those resetting)
        terminated = rt.terminated.copy()
        truncated = (rt.steps >= self.max_episode_steps) & ~terminated
        if resetting.any():
            self._reset_rows(np.flatnonzero(resetting))
            terminated[resetting] = truncated[resetting] = False
        if self.autoreset_mode == AutoresetMode.NEXT_STEP:
            self._done = terminated | truncated
            return rt.O.copy(), rt.R.copy(), terminated, truncated, self._info()
        self._done[:] = False
        done = terminated | truncated
        info = self._info()
        if done.any():  # SAME_STEP: report the last observation, then start afresh
            final_obs = np.empty(self.num_envs, dtype=object)
            for i in np.flatnonzero(done):
                final_obs[i] = rt.O[i].copy()
            info["final_obs"], info["_final_obs"] = final_obs, done
            info["final_info"] = {k: v for k, v in info.items() if not k.startswith("final")}
            info["_final_info"] = done
            rewards = rt.R.copy()
            self._reset_rows(np.flatnonzero(done))
            info = {**self._info(), **{k: info[k] for k in info if "final" in k}}
            return rt.O.copy(), rewards, terminated, truncated, info
        return rt.O.copy(), rt.R.copy(), terminated, truncated, info

    def _reset_rows(self, rows: np.ndarray) -> None:
        rows = rows.tolist()
        x, g, drawn = self._rt.start(self._rngs, None, rows, self.num_envs)
        self._rt.begin(rows, x, g, drawn, self._rngs)

    def _info(self, reset: bool = False) -> dict[str, Any]:
        rt = self._rt
        every = np.ones(self.num_envs, dtype=bool)
        info: dict[str, Any] = {
            "state": rt.X.copy(),
            "input": rt.U.copy(),
            "energy": rt.energy(),
        }
        if reset:
            info["goal"] = rt.G.copy()
        else:
            terms = rt.reward_terms()
            info["reward_terms"] = {**terms, **{"_" + k: every for k in terms}}
            info["is_success"] = rt.success.copy()
            info["diverged"] = rt.diverged.copy()
        if self.system.n_c:
            info["constraint_residual"] = rt.constraint_residual()
        if rt.per_row:  # randomised: the model parameters each copy steps with
            params = rt.params()
            info["params"] = {**params, **{"_" + k: every for k in params}}
        if rt.perturber is not None and rt.perturber.spec.push is not None:
            info["push"] = rt.perturber.force.copy()  # the push of the last step, N
        info.update({"_" + k: every for k in list(info)})
        return info

    def render(self):
        """rgb_array frames of every copy (a tuple), like Gymnasium's native vector envs."""
        if self.render_mode is None:
            gym.logger.warn("render() was called without render_mode='rgb_array'.")
            return None
        if self._viewer is None:
            self._viewer = rendering.Viewer("rgb_array", self.metadata["render_fps"])
        rt = self._rt
        rows = rt.rows().copy()
        return tuple(
            self._viewer.show(lambda s, i=i: draw(self, s, rows[i], rt.G[i].copy(), None))
            for i in range(self.num_envs)
        )

    def close_extras(self, **kwargs: Any) -> None:
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None

    def __getstate__(self):
        state = self.__dict__.copy()
        state["_viewer"] = None
        return state


def _seeds(seed, n: int) -> list:
    """Per-copy seeds of `seed`: an int s gives s, s + 1, ...; else a list of n ints or
    None (as SyncVectorEnv takes them)."""
    whole = (int, np.integer)
    if isinstance(seed, whole) and not isinstance(seed, bool):
        return [int(seed) + i for i in range(n)]
    ok = isinstance(seed, (list, tuple)) and all(
        s is None or (isinstance(s, whole) and not isinstance(s, bool)) for s in seed
    )
    if not ok or len(seed) != n:
        raise ValueError(f"seed must be an int or a list of {n} ints (or None), got {seed!r:.80}.")
    return list(seed)


__all__ = ["LagrangianEnv", "LagrangianVectorEnv"]
