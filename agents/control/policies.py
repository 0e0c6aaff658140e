"""Baseline policies with stable-baselines3's `predict` interface.

Every policy here (and `agents.control.lqr_policy.LQRPolicy`, and a trained SB3 model
through `agents.scoring.trained.SB3Policy`) answers `predict(observation, state=None,
episode_start=None, deterministic=True) -> (action, state)` for one observation or a batch,
so `stable_baselines3.common.evaluation.evaluate_policy` and `agents.evaluate` score them
alike.

The model-based baselines read the physics through the environment's contract
(`state_from_observation`, `operating_point`, `system`, `input_to_action`), never through
hand-typed equations: accelerations are affine in the inputs, so two evaluations of the
compiled dynamics per input give the exact input-to-acceleration matrix, and the power of
unit inputs gives the rate at which each one changes the energy.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np
from gymnasium import spaces

from dynamics import wrap

from ..common import UserError, lagrange_env


class Policy(ABC):
    """Base: batches the observation, calls `act`, clips to the action space [-1, 1]."""

    def __init__(self, action_space: spaces.Box):
        """action_space: the Box of one copy's actions, or an env (single or vector)."""
        if hasattr(action_space, "action_space"):
            action_space = getattr(action_space, "single_action_space", action_space.action_space)
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
    """Zero input: the unforced motion. Given a Lagrange env, the action that applies a
    physical input of 0 (not the middle of the range: for a one-sided input such as a
    rotor's thrust in [0, max], action -1), or the limit nearest 0 where an input's limits
    exclude it (then `description` says so); given only an action space, action 0."""

    def __init__(self, env):
        super().__init__(env)
        self.zero = np.zeros(self.action_space.shape)
        self.description = "zero input"
        try:
            plant = lagrange_env(env).plant
        except (UserError, AttributeError):
            return  # a bare action space: its middle
        exact = -plant.input_mid / plant.input_half
        self.zero = np.clip(exact, -1.0, 1.0).reshape(self.action_space.shape)
        if not np.allclose(self.zero, exact.reshape(self.zero.shape)):
            self.description = "zero input where the limits allow it, else the nearest limit"

    def act(self, obs):
        return np.broadcast_to(self.zero, (len(obs),) + self.action_space.shape).copy()


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
    """Model inputs the action drives, in action order."""
    return [int(i) for i in env.plant.actuated]


class GravityPDPolicy(Policy):
    """PD on the configuration error with gravity compensation, for a fully actuated arm.

    u = Bq(q)^-1 (w^2 e - 2 zeta w qdot - a0(q, 0)): the inputs that hold the arm at rest
    at q (gravity compensation, -Bq^-1 a0) plus a PD action whose gains are shaped by the
    inertia (Bq^-1 = M S^-1 maps accelerations to inputs), so every joint responds as a
    critically damped oscillator of natural frequency w (rad/s) until the torques saturate.
    e is the wrapped error to the goal of each observation."""

    def __init__(self, env, omega: float = 4.0, zeta: float = 1.0):
        self.env = lagrange_env(env)
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
    """Acrobot swing-up: energy pumping with a bounded elbow, straightening at the inverted
    energy, and LQR inside its measured basin.

    Three regimes, by state (x = [theta1, theta2, theta1', theta2'], rel = theta2 - theta1
    wrapped, gap = E* - E with E* the energy of the goal at rest):
    - pump: a = k_energy gap p(x), p the power each unit action delivers (the elbow's
      M2 rel'), so dE/dt = k_energy gap |p|^2 >= 0 below E*; while |rel| > `rel_max` a PD
      (`k_p`, `k_d`) pushes the elbow back instead, so the energy goes into swinging the
      whole arm rather than spinning link 2.
    - straighten (gap < `straighten_gap` J): collocated partial feedback linearisation
      (Spong 1995) of the elbow, rel'' = -omega^2 rel - 2 zeta omega rel', solved for the
      torque from the exact affine input response. A straight arm at E* rides the
      homoclinic orbit of the rigid pendulum towards inverted; along it the elbow needs
      at most 1.23 N*m for the default arm (below the 3 N*m limit).
    - balance: LQR once its cost-to-go dx' P dx is below `capture_level` (the level set
      from which LQR succeeds in 99 % of 200 random directions for the default acrobot;
      the task's LQR region is far smaller because the basin is a thin slab, see agents.lqr).
    Measured on the 3 N*m acrobot (Lagrange/Acrobot-v1), 50 episodes: success 20 % (seeds
    0-49) and 16 % (seeds 1000-1049); the energy-only pump it replaces captured none. The other
    episodes keep swinging at about E* without passing through the hand-over set."""

    def __init__(
        self,
        env,
        lqr=None,
        k_energy: float = 1.0 / 3.0,
        rel_max: float = 1.5,
        k_p: float = 3.0,
        k_d: float = 0.5,
        straighten_gap: float = 0.5,
        omega: float = 6.3,
        zeta: float = 0.8,
        capture_level: float = 500.0,
    ):
        from .lqr_policy import LQRPolicy

        self.env = lagrange_env(env)
        super().__init__(_single_action_space(self.env))
        self.system = self.env.system
        if self.system.n_q != 2 or self.system.n_c:
            raise ValueError(
                f"SwingUpPolicy needs a two-link arm (two coordinates, no constraints); "
                f"{self.system.name} has {self.system.n_q} coordinates and "
                f"{self.system.n_c} constraints."
            )
        gains = dict(rel_max=rel_max, k_p=k_p, k_d=k_d, omega=omega, zeta=zeta)
        bad = {k: v for k, v in gains.items() if not (np.isfinite(v) and v > 0)}
        if bad or not (np.isfinite(k_energy) and k_energy >= 0) or not capture_level >= 0:
            raise ValueError(
                f"SwingUpPolicy gains must be positive (k_energy, capture_level >= 0); got "
                f"{bad or dict(k_energy=k_energy, capture_level=capture_level)}."
            )
        self.lqr = lqr if lqr is not None else LQRPolicy(env)
        self.actuated = _actuated(self.env)
        self.k_energy, self.rel_max = float(k_energy), float(rel_max)
        self.k_p, self.k_d = float(k_p), float(k_d)
        self.straighten_gap = float(straighten_gap)
        self.omega, self.zeta = float(omega), float(zeta)
        self.capture_level = float(capture_level)

    def _power_per_action(self, x: np.ndarray) -> np.ndarray:
        """dE/dt per unit of each action component at states x, W, shape (N, n_a)."""
        n_a = len(self.actuated)
        cols = []
        for k in range(n_a):
            u = self.env.action_to_input(np.eye(n_a)[k])
            cols.append(self.system.power(0.0, x, np.broadcast_to(u, (len(x), len(u)))))
        return np.stack(cols, axis=-1)

    def act(self, obs):
        env = self.env
        x = env.state_from_observation(obs)
        x0, u0 = env.operating_point(obs)
        gap = self.system.energy(x0) - self.system.energy(x)  # E* - E, J
        rel = wrap(x[:, 1] - x[:, 0])
        rel_rate = x[:, 3] - x[:, 2]
        a = self.k_energy * gap[:, None] * self._power_per_action(x)
        bent = np.abs(rel) > self.rel_max
        excess = rel - np.sign(rel) * self.rel_max
        a[bent] = -(self.k_p * excess[bent] + self.k_d * rel_rate[bent])[:, None]
        straight = gap < self.straighten_gap
        if straight.any():
            a0, Bq = input_response(self.system, x[straight], self.actuated)
            want = (
                -(self.omega**2) * rel[straight] - 2 * self.zeta * self.omega * rel_rate[straight]
            )
            b = Bq[:, 1, 0] - Bq[:, 0, 0]  # rel'' per unit input
            u = np.zeros((int(straight.sum()), self.system.n_u))
            u[:, self.actuated[0]] = (want - (a0[:, 1] - a0[:, 0])) / b
            a[straight] = env.input_to_action(u)
        near = self.lqr.cost_to_go(x, x0, u0) < self.capture_level
        if near.any():
            a[near] = self.lqr.act(x[near], x0[near], u0[near])
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
        self.env = lagrange_env(env)
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
