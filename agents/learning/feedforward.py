"""The holding input as a feed-forward: the agent's action is added to the action that holds
the current configuration at rest (the plant's operating input of the observed state with
its rates zeroed: gravity's and the springs' torque, in the env's normalised action units),
and the sum is clipped to [-1, 1]. A goal-conditioned task that holds against gravity then
asks the policy for a correction that is zero at the goal whatever the goal, not for the
holding torque itself: a policy whose resting action misses that torque by a few
hundredths of the action range rests that far from the goal (the three-link arm example's
misses, docs/learning.md).

It is a derived default (agents.learning.defaults) where `holds_at_rest`: the inputs can
hold every configuration at rest. `FeedForwardVecEnv` adds it in training and in
training's evaluations (inside the LQR hand-over, which overrides the sum where it acts);
`FeedForwardPolicy` adds it to a loaded agent's actions (agents.scoring.trained)."""

from __future__ import annotations

import numpy as np
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from ..common import lagrange_env, lagrange_of


def holds_at_rest(plant) -> bool:
    """Whether the plant's inputs hold every configuration at rest, at every time: as many
    actuated inputs as coordinates, no constraint, dynamics that do not depend on time, and
    the operating input zeroes the accelerations at the plant's sample states at rest."""
    s = plant.system
    if s.n_c or len(plant.actuated) != s.n_q or plant.time_dependent:
        return False
    x = plant.sample_states(4).copy()
    x[:, s.n_q :] = 0.0
    a0 = s.accelerations(0.0, x, np.zeros((len(x), s.n_u)))
    a = s.accelerations(0.0, x, plant.operating_input(x))
    # round-off of one pseudo-inverse against the accelerations the inputs cancel
    return bool(np.all(np.abs(a) <= 1e-8 * (1.0 + np.abs(a0).max())))


def operating_action(env, obs: np.ndarray) -> np.ndarray:
    """(N, n_a): the normalised action that holds each row's configuration at rest (the
    plant's operating input of its state with the rates zeroed: gravity's torque)."""
    obs = np.asarray(obs, dtype=np.float64).reshape(len(obs), -1)
    x = env.state_from_observation(obs).copy()
    x[:, env.system.n_q :] = 0.0
    u = env.plant.operating_input(x)
    return np.clip(env.input_to_action(u), -1.0, 1.0)


def fed_forward(env, obs: np.ndarray, actions) -> np.ndarray:
    """(N, n_a) float32: `actions` plus `operating_action` of each row of `obs`, clipped to
    [-1, 1]."""
    a = np.asarray(actions, dtype=np.float64) + operating_action(env, obs)
    return np.clip(a, -1.0, 1.0).astype(np.float32)


class FeedForwardVecEnv(VecEnvWrapper):
    """Training env whose actions are the agent's plus `operating_action` of the last
    observation (see the module docstring). Goes inside VecNormalize: it reads raw
    observations."""

    def __init__(self, venv: VecEnv):
        super().__init__(venv)
        self.env = lagrange_of(venv)
        self._obs: np.ndarray | None = None

    def reset(self):
        self._obs = self.venv.reset()
        return self._obs

    def step_async(self, actions: np.ndarray) -> None:
        self.venv.step_async(fed_forward(self.env, self._obs, actions))

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
        if obs.ndim == 1:  # one observation
            return fed_forward(self.env, obs[None], np.asarray(a)[None])[0], state
        return fed_forward(self.env, obs, a), state
