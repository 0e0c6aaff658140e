"""RL that hands over to LQR inside its basin (as the DFKI double-pendulum benchmark's
SAC+LQR controller does): the learnt policy only has to bring the system into the set
where LQR's cost-to-go dx' P dx is below a capture level; LQR holds it from there.

A task asks for it in its hyperparameters, `"handover": {"level": L, "shaping": c}`:
- training (`HandOverVecEnv`) runs the same switch the trained agent runs, so the agent
  learns in the closed loop it will act in; `shaping` > 0 adds the potential-based term
  gamma Phi(x') - Phi(x) with Phi = -c |E - E*| / |E* - E0| (E* the operating point's
  energy, E0 the start centre's), which leaves the optimal policy unchanged (Ng, Harada and
  Russell 1999) and pays for pumping energy towards E*;
- evaluation (`HandOverPolicy`, what `SB3Policy.load` returns for such a run) acts with
  the trained model outside the set and LQR inside.
The level is a measured statement about the basin: the task's tests check that LQR
captures from random directions on that level set.
"""

from __future__ import annotations

import numpy as np
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from .common import UserError, lagrange_env
from .lqr import LQRPolicy


def handover_options(raw) -> dict | None:
    """The checked `handover` entry of a hyperparameter table (None when absent)."""
    if raw is None:
        return None
    if not isinstance(raw, dict) or set(raw) - {"level", "shaping"} or "level" not in raw:
        raise UserError(
            f"handover must be a table with 'level' (and optionally 'shaping'), got {raw!r}."
        )
    level, shaping = float(raw["level"]), float(raw.get("shaping", 0.0))
    if not (np.isfinite(level) and level > 0) or not (np.isfinite(shaping) and shaping >= 0):
        raise UserError(
            f"handover level must be positive and shaping non-negative, got {level}, {shaping}."
        )
    return {"level": level, "shaping": shaping}


class CaptureSet:
    """States inside LQR's level set dx' P dx < level about each row's operating point."""

    def __init__(self, env, level: float, lqr: LQRPolicy | None = None):
        self.env = lagrange_env(env)
        self.lqr = lqr if lqr is not None else LQRPolicy(self.env)
        self.level = float(level)

    def split(self, obs: np.ndarray):
        """(states, operating states, inputs, inside) of a batch of observations."""
        obs = np.asarray(obs, dtype=np.float64).reshape(-1, self.env.observation_space.shape[-1])
        x = self.env.state_from_observation(obs)
        x0, u0 = self.env.operating_point(obs)
        return x, x0, u0, self.lqr.cost_to_go(x, x0, u0) < self.level

    def override(self, obs: np.ndarray, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """`actions` with LQR's in the rows inside the set; and which rows those are."""
        x, x0, u0, inside = self.split(obs)
        actions = np.array(actions, dtype=np.float32).reshape(len(x), -1)
        if inside.any():
            actions[inside] = self.lqr.act(x[inside], x0[inside], u0[inside])
        return actions, inside


class HandOverPolicy:
    """A trained policy outside the capture set, LQR inside (SB3's `predict`)."""

    def __init__(self, policy, env, level: float):
        self.policy = policy
        self.model = getattr(policy, "model", None)  # for checks of the model's spaces
        self.capture = CaptureSet(env, level)

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        obs = np.asarray(observation)
        actions, state = self.policy.predict(obs, state, episode_start, deterministic)
        a, _ = self.capture.override(obs, actions)
        return a.reshape(np.shape(actions)), state


def _lagrange_of(venv: VecEnv):
    """The Lagrange env under SB3 wrappers (a native vector env or DummyVecEnv's first)."""
    inner = venv
    while True:
        if hasattr(inner, "envs"):  # DummyVecEnv / SubprocVecEnv-like
            return lagrange_env(inner.envs[0])
        nxt = getattr(inner, "venv", None)
        if nxt is None:
            return lagrange_env(inner)
        inner = nxt


class HandOverVecEnv(VecEnvWrapper):
    """Training env: LQR overrides the agent's actions inside the capture set, and the
    reward adds the potential-based energy shaping (see the module docstring). Goes
    inside VecNormalize and outside the episode monitor, so the logged returns are the
    env's own."""

    def __init__(self, venv: VecEnv, level: float, shaping: float = 0.0, gamma: float = 0.99):
        super().__init__(venv)
        self.capture = CaptureSet(_lagrange_of(venv), level)
        self.shaping, self.gamma = float(shaping), float(gamma)
        self._obs: np.ndarray | None = None
        self.lqr_steps = 0
        self._scale: float | None = None

    def _potential(self, obs: np.ndarray) -> np.ndarray:
        env = self.capture.env
        x = env.state_from_observation(np.asarray(obs, dtype=np.float64))
        x0, _ = env.operating_point(np.asarray(obs, dtype=np.float64))
        gap = np.abs(env.system.energy(x) - env.system.energy(x0))
        return -self.shaping * gap / self._energy_scale(x0[0])

    def _energy_scale(self, x0: np.ndarray) -> float:
        if self._scale is None:
            from .tvlqr import start_centre

            env = self.capture.env
            centre = start_centre(env)
            e = env.system.energy(np.stack([x0, x0 if centre is None else centre]))
            self._scale = float(abs(e[0] - e[1])) or 1.0
        return self._scale

    def reset(self):
        self._obs = self.venv.reset()
        return self._obs

    def step_async(self, actions: np.ndarray) -> None:
        actions, inside = self.capture.override(self._obs, actions)
        self.lqr_steps += int(inside.sum())
        self.venv.step_async(actions.reshape((self.num_envs, *self.action_space.shape)))

    def step_wait(self):
        obs, rewards, dones, infos = self.venv.step_wait()
        if self.shaping:
            after = obs.copy()
            ended = np.zeros(len(dones), dtype=bool)  # terminal states have potential 0
            for i in np.flatnonzero(dones):
                after[i] = infos[i]["terminal_observation"]
                ended[i] = not infos[i].get("TimeLimit.truncated", False)
            shaped = self.gamma * np.where(ended, 0.0, self._potential(after))
            rewards = (rewards + shaped - self._potential(self._obs)).astype(np.float32)
        self._obs = obs
        return obs, rewards, dones, infos
