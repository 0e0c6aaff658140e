"""The operating input as a feed-forward: the agent's action is added to the action that
holds the task's operating point (u0 of the goal in each observation, in the env's
normalised action units), and the sum is clipped to [-1, 1]. A goal-conditioned task that
holds against gravity then asks the policy for a correction around the holding torque, not
for the holding torque itself: a policy whose resting action misses it by a few hundredths
of the action range rests that far from the goal (the three-link arm example's misses).

`FeedForwardVecEnv` adds it in training and in training's evaluations (inside the LQR
hand-over, which overrides the sum where it acts); `FeedForwardPolicy` adds it to a loaded
agent's actions (agents.scoring.trained)."""

from __future__ import annotations

import numpy as np
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from ..common import lagrange_env


def operating_action(env, obs: np.ndarray) -> np.ndarray:
    """(N, n_a): the normalised action that holds each row's configuration at rest (the
    plant's operating input of its state with the rates zeroed: gravity's torque)."""
    obs = np.asarray(obs, dtype=np.float64).reshape(len(obs), -1)
    x = env.state_from_observation(obs).copy()
    x[:, env.system.n_q :] = 0.0
    u = env.plant.operating_input(x)
    return np.clip(env.input_to_action(u), -1.0, 1.0)


class FeedForwardVecEnv(VecEnvWrapper):
    """Training env whose actions are the agent's plus `operating_action` of the last
    observation (see the module docstring). Goes inside VecNormalize: it reads raw
    observations."""

    def __init__(self, venv: VecEnv):
        super().__init__(venv)
        from ..control.handover import _lagrange_of

        self.env = _lagrange_of(venv)
        self._obs: np.ndarray | None = None

    def reset(self):
        self._obs = self.venv.reset()
        return self._obs

    def step_async(self, actions: np.ndarray) -> None:
        a = np.asarray(actions, dtype=np.float64) + operating_action(self.env, self._obs)
        self.venv.step_async(np.clip(a, -1.0, 1.0).astype(np.float32))

    def step_wait(self):
        obs, rewards, dones, infos = self.venv.step_wait()
        self._obs = obs  # after an episode's end, the next one's first observation
        return obs, rewards, dones, infos


class FeedForwardPolicy:
    """A policy's actions plus the operating action of each observation, clipped."""

    def __init__(self, policy, env):
        self.policy, self.env = policy, lagrange_env(env)

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        a, state = self.policy.predict(observation, state, episode_start, deterministic)
        obs = np.asarray(observation)
        single = obs.ndim == 1
        a0 = operating_action(self.env, obs[None] if single else obs)
        out = np.clip(np.asarray(a, dtype=np.float64) + (a0[0] if single else a0), -1.0, 1.0)
        return out.astype(np.float32), state
