"""Baseline policies with stable-baselines3's `predict` interface.

Every policy here (and `agents.lqr.LQRPolicy`, and a trained SB3 model through
`SB3Policy`) answers `predict(observation, state=None, episode_start=None,
deterministic=True) -> (action, state)` for one observation or a batch, so
`stable_baselines3.common.evaluation.evaluate_policy` and `agents.evaluate` score them alike.

The model-based baselines read the physics through the environment's contract
(`state_from_observation`, `operating_point`, `system`, `input_to_action`), never through
hand-typed equations: accelerations are affine in the inputs, so two evaluations of the
compiled dynamics per input give the exact input-to-acceleration matrix, and the power of
unit inputs gives the rate at which each one changes the energy.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from pathlib import Path

import numpy as np
from gymnasium import spaces


def wrap(a: np.ndarray) -> np.ndarray:
    """Angles wrapped to [-pi, pi)."""
    return (a + np.pi) % (2 * np.pi) - np.pi


class Policy(ABC):
    """Base: batches the observation, calls `act`, clips to the action space [-1, 1]."""

    def __init__(self, action_space: spaces.Box):
        if not isinstance(action_space, spaces.Box):
            raise TypeError(f"Expected a Box action space, got {action_space!r}.")
        self.action_space = action_space

    @abstractmethod
    def act(self, obs: np.ndarray) -> np.ndarray:
        """Actions (N, n_a) for observations (N, n_obs)."""

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        obs = np.asarray(observation, dtype=np.float64)
        flat = obs.reshape(-1, obs.shape[-1])
        a = np.clip(self.act(flat), self.action_space.low, self.action_space.high)
        return a.astype(np.float32).reshape(obs.shape[:-1] + self.action_space.shape), state


class RandomPolicy(Policy):
    """Uniform random actions (its own seeded generator)."""

    def __init__(self, action_space: spaces.Box, seed: int | None = None):
        super().__init__(action_space)
        self.rng = np.random.default_rng(seed)

    def act(self, obs):
        low, high = self.action_space.low, self.action_space.high
        return self.rng.uniform(low, high, (len(obs),) + self.action_space.shape)


class ZeroPolicy(Policy):
    """No torque: the unforced motion."""

    def act(self, obs):
        return np.zeros((len(obs),) + self.action_space.shape)


def _unwrapped(env):
    return env.unwrapped if hasattr(env, "unwrapped") else env


def _single_action_space(env) -> spaces.Box:
    """The action space of one copy (a vector env's `single_action_space`)."""
    return getattr(env, "single_action_space", env.action_space)


def input_response(system, x: np.ndarray, actuated: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """(a0, Bq): qddot = a0 + Bq u_actuated at states x (N, 2n), exact because the
    accelerations are affine in the inputs. Shapes (N, n) and (N, n, n_a)."""
    u = np.zeros((len(x), system.n_u))
    a0 = system.accelerations(0.0, x, u)
    cols = []
    for j in actuated:
        e = u.copy()
        e[:, j] = 1.0
        cols.append(system.accelerations(0.0, x, e) - a0)
    return a0, np.stack(cols, axis=-1)


def _actuated(env) -> list[int]:
    """Model inputs the action drives (columns of the action scaling)."""
    n_a = _single_action_space(env).shape[-1]
    S = env.action_to_input(np.eye(n_a)) - env.action_to_input(np.zeros(n_a))
    return [int(np.argmax(np.abs(row))) for row in S]


class GravityPDPolicy(Policy):
    """PD on the configuration error with gravity compensation, for a fully actuated arm.

    u = Bq(q)^-1 (w^2 e - 2 zeta w qdot - a0(q, 0)): the inputs that hold the arm at rest
    at q (gravity compensation, -Bq^-1 a0) plus a PD action whose gains are shaped by the
    inertia (Bq^-1 = M S^-1 maps accelerations to inputs), so every joint responds as a
    critically damped oscillator of natural frequency w (rad/s) until the torques saturate.
    e is the wrapped error to the goal of each observation."""

    def __init__(self, env, omega: float = 4.0, zeta: float = 1.0):
        self.env = _unwrapped(env)
        super().__init__(_single_action_space(self.env))
        self.system = self.env.system
        self.actuated = _actuated(self.env)
        if len(self.actuated) != self.system.n_q or self.system.n_c:
            raise ValueError(
                f"GravityPDPolicy needs one actuated input per coordinate and no constraints; "
                f"{self.system.name} has {self.system.n_q} coordinates, "
                f"{len(self.actuated)} actuated inputs and {self.system.n_c} constraints."
            )
        if not (omega > 0 and zeta > 0):
            raise ValueError(f"omega and zeta must be positive, got {omega}, {zeta}.")
        self.omega, self.zeta = float(omega), float(zeta)
        self.periodic = np.asarray(self.env.periodic, dtype=bool)

    def act(self, obs):
        env, n = self.env, self.system.n_q
        x = env.state_from_observation(obs)
        x0, _ = env.operating_point(obs)
        e = x0[:, :n] - x[:, :n]
        e[:, self.periodic] = wrap(e[:, self.periodic])
        rest = np.concatenate([x[:, :n], np.zeros_like(x[:, n:])], axis=1)
        a0, Bq = input_response(self.system, rest, self.actuated)
        desired = self.omega**2 * e - 2 * self.zeta * self.omega * x[:, n:] - a0
        u = np.zeros((len(x), self.system.n_u))
        u[:, self.actuated] = np.linalg.solve(Bq, desired[..., None])[..., 0]
        return env.input_to_action(u)


class SwingUpPolicy(Policy):
    """Energy-pumping swing-up for an underactuated arm, handing over to LQR near the goal.

    Away from the goal: a = k_E (E* - E) p(x) - k_p rel - k_d rel', where E* is the energy
    of the goal at rest, p the power each unit action delivers at the current state (so the
    first term makes dE/dt = k_E (E* - E) |p|^2 >= 0 below E*: energy rises to E*
    monotonically), and rel the wrapped angle between the links (the PD damps the elbow).
    Measured on Lagrange/Acrobot-v0 (3 N*m elbow): the energy reaches E* within ~3 s, but
    it goes into spinning the second link, so the arm does not come near the capture
    region; this baseline shows what energy pumping alone achieves there.
    Near the goal (every wrapped angle error below `capture_angle` rad and every rate below
    `capture_rate` rad/s) the LQR policy acts."""

    def __init__(
        self,
        env,
        lqr=None,
        k_energy: float = 2.0,
        k_p: float = 1.0,
        k_d: float = 0.3,
        capture_angle: float = 0.5,
        capture_rate: float = 2.0,
    ):
        from .lqr import LQRPolicy

        self.env = _unwrapped(env)
        super().__init__(_single_action_space(self.env))
        self.system = self.env.system
        self.lqr = lqr if lqr is not None else LQRPolicy(env)
        self.actuated = _actuated(self.env)
        self.k_energy, self.k_p, self.k_d = float(k_energy), float(k_p), float(k_d)
        self.capture_angle, self.capture_rate = float(capture_angle), float(capture_rate)
        self.periodic = np.asarray(self.env.periodic, dtype=bool)

    def _power_per_action(self, x: np.ndarray) -> np.ndarray:
        """dE/dt per unit of each action component at states x, W, shape (N, n_a)."""
        n_a = len(self.actuated)
        cols = []
        for k in range(n_a):
            u = self.env.action_to_input(np.eye(n_a)[k])
            cols.append(self.system.power(0.0, x, np.broadcast_to(u, (len(x), len(u)))))
        return np.stack(cols, axis=-1)

    def act(self, obs):
        env, n = self.env, self.system.n_q
        x = env.state_from_observation(obs)
        x0, u0 = env.operating_point(obs)
        e = x[:, :n] - x0[:, :n]
        e[:, self.periodic] = wrap(e[:, self.periodic])
        near = (np.abs(e) < self.capture_angle).all(axis=1) & (
            np.abs(x[:, n:]) < self.capture_rate
        ).all(axis=1)
        gap = self.system.energy(x0) - self.system.energy(x)  # E* - E, J
        rel = wrap(x[:, 1] - x[:, 0])[:, None]
        rel_rate = (x[:, n + 1] - x[:, n])[:, None]
        a = self.k_energy * gap[:, None] * self._power_per_action(x)
        a -= self.k_p * rel + self.k_d * rel_rate
        if near.any():
            a[near] = self.lqr.predict(obs[near])[0]
        return a


class BeadCascadePolicy(Policy):
    """Ball-and-beam cascade for the bead on a driven rod (coordinates r, phi).

    Outer loop: the rod angle phi_d that would bring the bead to its target like a
    critically damped oscillator of frequency `omega_outer`, through the exact
    linearisation r'' ~ c (phi - phi0) at the operating point (c = -g for a level rod),
    limited to +-`max_tilt` rad. Inner loop: collocated feedback linearisation of the rod,
    phi'' = w^2 (phi_d - phi) - 2 w phi', solved for the torque from the exact affine
    input response."""

    def __init__(self, env, omega_outer: float = 1.5, omega_inner: float = 8.0, max_tilt=0.5):
        self.env = _unwrapped(env)
        super().__init__(_single_action_space(self.env))
        self.system = self.env.system
        if self.system.coordinates != ("r", "phi"):
            raise ValueError(
                f"BeadCascadePolicy needs coordinates (r, phi), got {self.system.coordinates}."
            )
        self.actuated = _actuated(self.env)
        self.wo, self.wi, self.max_tilt = float(omega_outer), float(omega_inner), float(max_tilt)

    def act(self, obs):
        env = self.env
        x = env.state_from_observation(obs)
        x0, u0 = env.operating_point(obs)
        c = np.array([self.system.linearize(x0[i], u0[i])[0][2, 1] for i in range(len(x))])
        r_err, r_rate = x[:, 0] - x0[:, 0], x[:, 2]
        tilt = -(self.wo**2 * r_err + 2 * self.wo * r_rate) / c
        phi_d = x0[:, 1] + np.clip(tilt, -self.max_tilt, self.max_tilt)
        a0, Bq = input_response(self.system, x, self.actuated)
        want = self.wi**2 * (phi_d - x[:, 1]) - 2 * self.wi * x[:, 3]
        u = np.zeros((len(x), self.system.n_u))
        u[:, self.actuated[0]] = (want - a0[:, 1]) / Bq[:, 1, 0]
        return env.input_to_action(u)


class SB3Policy:
    """A trained stable-baselines3 model with its VecNormalize observation statistics."""

    def __init__(self, model, obs_rms=None, clip_obs: float = 10.0, epsilon: float = 1e-8):
        self.model = model
        self.obs_rms = obs_rms
        self.clip_obs, self.epsilon = clip_obs, epsilon

    @classmethod
    def load(cls, path: str | Path) -> SB3Policy:
        """Load model.zip (the algorithm read from config.yml beside it, or tried in turn)
        and vecnormalize.pkl if it is there."""
        import pickle

        import yaml
        from stable_baselines3 import PPO, SAC, TD3

        path = Path(path)
        if path.is_dir():
            path = path / "model.zip"
        if not path.is_file():
            raise FileNotFoundError(f"No trained model at {path}.")
        config = path.parent / "config.yml"
        algos = {"ppo": PPO, "sac": SAC, "td3": TD3}
        order = list(algos)
        if config.exists():
            order.insert(0, yaml.safe_load(config.read_text(encoding="utf-8"))["algo"])
        model, errors = None, []
        for name in dict.fromkeys(order):
            try:
                model = algos[name].load(path, device="cpu")
                break
            except (ValueError, KeyError, TypeError, AttributeError) as exc:
                errors.append(f"{name}: {exc}")
        if model is None:
            raise ValueError(f"{path} is not a PPO, SAC or TD3 model ({'; '.join(errors)}).")
        stats = path.parent / "vecnormalize.pkl"
        if not stats.exists():
            return cls(model)
        with open(stats, "rb") as fh:
            vecnorm = pickle.load(fh)
        if not vecnorm.norm_obs:
            return cls(model)
        return cls(model, vecnorm.obs_rms, vecnorm.clip_obs, vecnorm.epsilon)

    def normalize(self, obs: np.ndarray) -> np.ndarray:
        if self.obs_rms is None:
            return obs
        z = (obs - self.obs_rms.mean) / np.sqrt(self.obs_rms.var + self.epsilon)
        return np.clip(z, -self.clip_obs, self.clip_obs).astype(np.float32)

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        obs = np.asarray(observation, dtype=np.float32)
        return self.model.predict(self.normalize(obs), state, episode_start, deterministic)
