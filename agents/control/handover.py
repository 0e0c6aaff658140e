"""RL that hands over to LQR inside its basin (as the DFKI double-pendulum benchmark's
SAC+LQR controller does): the learnt policy only has to bring the system into LQR's
basin; LQR holds it from there.

The basin is known two ways. Inside the level set where LQR's cost-to-go V = dx' P dx is
below `level`, LQR takes over outright (a measured statement: the task's tests check that
LQR captures from random directions on that set). With `verify` = T seconds, a state
outside it but with V below `verify_level` (default 20 x level) is in the basin when LQR's
closed loop, simulated from it on the env's own model (the same runtime and integrator,
so the simulation is what the env will do), ends in the task's success after T seconds
without ending early. The ellipsoid is conservative along the directions in which the
saturated LQR still recovers and the simulation finds those states; on Acrobot-v2 a PPO
policy that enters the ellipsoid in 56 % of episodes is caught in 100 % with the check.

A task asks for it in its hyperparameters, `"handover": {"level": L, "shaping": c,
"verify": T, "verify_level": L2}`:
- training (`HandOverVecEnv`) switches to LQR inside the level set only, so the agent
  learns to aim at the ellipsoid, and acting adds the verified states to it (on
  Acrobot-v2, seed 0, 3M steps, training with the check too made the agent sloppier: 72 %
  success, against 97 % for the same settings trained on the ellipsoid); `shaping` adds the
  potential-based term gamma Phi(x') - Phi(x) with Phi = -c |E - E*| / |E* - E0| (E* the
  operating point's energy, E0 the start centre's), which leaves the optimal policy
  unchanged (Ng, Harada and Russell 1999) and pays for pumping energy towards E*;
- evaluation (`HandOverPolicy`, what `SB3Policy.load` returns for such a run) acts with
  the trained model outside the set and LQR inside.
The level is a measured statement about the basin: the task's tests check that LQR
captures from random directions on that level set.
"""

from __future__ import annotations

import numpy as np
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from ..common import UserError, lagrange_env, lagrange_of
from .lqr_policy import LQRPolicy

HANDOVER_KEYS = ("level", "shaping", "verify", "verify_level")
MAX_SHAPING = 1e6
"""The largest shaping coefficient: the energy gap is scaled to about 1 per unit, so the
shaping term is then a million times a typical reward term, and 1e308 made it infinite."""
VERIFY_REACH = 20.0
"""The default verify_level in levels: the acrobot's PPO passes within 1-3 levels of the
set when it misses it (see the module docstring)."""


VERIFY_MAX = 60.0
"""The longest `verify` simulation, seconds: each check simulates LQR that long for every
row near the set, inside the env's step (the acrobot uses 3 s)."""


def handover_options(raw) -> dict | None:
    """The checked `handover` entry of a hyperparameter table (None when absent)."""
    if raw is None:
        return None
    try:
        return check_handover(raw)
    except ValueError as exc:
        from ..values import short

        raise UserError(f"handover must be {exc}, got {short(raw)}.") from None


def check_handover(raw) -> dict:
    """The `handover` table with its defaults; ValueError saying what it must be."""
    if not isinstance(raw, dict) or set(raw) - set(HANDOVER_KEYS) or "level" not in raw:
        raise ValueError(f"a table with 'level' (and optionally {', '.join(HANDOVER_KEYS[1:])})")
    numbers = all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v)
        for v in raw.values()
    )
    if not numbers:
        raise ValueError("a table of finite numbers")
    level = float(raw["level"])
    out = {"level": level, "verify_level": VERIFY_REACH * level, "shaping": 0.0, "verify": 0.0}
    out.update({k: float(v) for k, v in raw.items()})
    if not (
        out["level"] > 0
        and out["verify_level"] >= out["level"]
        and 0 <= out["shaping"] <= MAX_SHAPING
        and 0 <= out["verify"] <= VERIFY_MAX
    ):
        raise ValueError(
            "a table with a positive level, verify_level at least the level, shaping in "
            f"[0, {MAX_SHAPING:g}] "
            f"and verify in [0, {VERIFY_MAX:g}] seconds"
        )
    return out


class CaptureSet:
    """States in LQR's basin about each row's operating point: inside the level set
    dx' P dx < level, or (with `verify` seconds) verified by simulating LQR from them (see
    the module docstring)."""

    def __init__(
        self,
        env,
        level: float,
        lqr: LQRPolicy | None = None,
        verify: float = 0.0,
        verify_level: float | None = None,
    ):
        self.env = lagrange_env(env)
        self.lqr = lqr if lqr is not None else LQRPolicy(self.env)
        self.level = float(level)
        if not 0 <= float(verify) <= VERIFY_MAX:
            raise ValueError(f"verify must be in [0, {VERIFY_MAX:g}] seconds, got {verify}.")
        self.verify_steps = int(np.ceil(float(verify) / self.env.control_period - 1e-9))
        reach = VERIFY_REACH * self.level
        self.verify_level = reach if verify_level is None else float(verify_level)
        self.simulated = 0  # rows checked by simulation (for reports)
        self._sims: dict = {}

    def split(self, obs: np.ndarray):
        """(states, operating states, inputs, inside) of a batch of observations."""
        x, x0, u0, cost = self.cost(obs)
        inside = cost < self.level
        if self.verify_steps:
            rows = np.flatnonzero(~inside & (cost < self.verify_level))
            if len(rows):
                obs = np.asarray(obs, dtype=np.float64).reshape(len(x), -1)
                g = self.env.goal_from_observation(obs[rows])
                inside[rows] = self.captures(x[rows], g, x0[rows], u0[rows])
        return x, x0, u0, inside

    def captures(self, x: np.ndarray, g: np.ndarray, x0: np.ndarray, u0: np.ndarray):
        """Whether LQR, simulated from states x (goals g) on the env's model for the
        `verify` horizon, ends in the task's success without ending early (per row)."""
        m = len(x)
        self.simulated += m
        sim = self._sims.get(m)
        if sim is None:
            env = self.env
            sim = env.simulator(m)
            self._sims[m] = sim
        sim.reset_rows(np.arange(m), x, g)
        ended = np.zeros(m, dtype=bool)
        for _ in range(self.verify_steps):
            sim.step(self.lqr.act(sim.X, x0, u0), None)
            ended |= sim.terminated
        return sim.success & ~ended

    def cost(self, obs: np.ndarray):
        """(states, operating states, inputs, LQR's cost-to-go) of a batch of observations."""
        obs = np.asarray(obs, dtype=np.float64).reshape(-1, self.env.observation_space.shape[-1])
        x = self.env.state_from_observation(obs)
        x0, u0 = self.env.operating_point(obs)
        return x, x0, u0, self.lqr.cost_to_go(x, x0, u0)

    def override(self, obs: np.ndarray, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """`actions` with LQR's in the rows inside the set; and which rows those are."""
        x, x0, u0, inside = self.split(obs)
        actions = np.array(actions, dtype=np.float32).reshape(len(x), -1)
        if inside.any():
            actions[inside] = self.lqr.act(x[inside], x0[inside], u0[inside])
        return actions, inside


class HandOverPolicy:
    """A trained policy outside the capture set, LQR inside (SB3's `predict`)."""

    def __init__(self, policy, env, level: float, verify: float = 0.0, verify_level=None):
        self.policy = policy
        self.model = getattr(policy, "model", None)  # for checks of the model's spaces
        self.capture = CaptureSet(env, level, verify=verify, verify_level=verify_level)
        self.steps = self.lqr_steps = 0  # rows acted on, and of those by LQR (for reports)

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        obs = np.asarray(observation)
        actions, state = self.policy.predict(obs, state, episode_start, deterministic)
        a, inside = self.capture.override(obs, actions)
        self.steps += len(inside)
        self.lqr_steps += int(inside.sum())
        return a.reshape(np.shape(actions)), state


class HandOverVecEnv(VecEnvWrapper):
    """Training env: LQR overrides the agent's actions inside the capture set (training
    passes no `verify`; the evaluation env does), and the reward adds the potential-based
    energy shaping (see the module docstring). Goes
    inside VecNormalize and outside the episode monitor, so the logged returns are the
    env's own."""

    def __init__(
        self,
        venv: VecEnv,
        level: float,
        shaping: float = 0.0,
        gamma: float = 0.99,
        verify: float = 0.0,
        verify_level: float | None = None,
    ):
        super().__init__(venv)
        self.capture = CaptureSet(
            lagrange_of(venv), level, verify=verify, verify_level=verify_level
        )
        self.shaping, self.gamma = float(shaping), float(gamma)
        self._obs: np.ndarray | None = None
        self.lqr_steps = 0
        self._scale: float | None = None

    def _potential(self, obs: np.ndarray) -> np.ndarray:
        env = self.capture.env
        x, x0, _, _ = self.capture.cost(obs)
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
