"""LQR from the exact linearisation of an environment's equations of motion.

The chain: linearise the compiled `System` at the task's operating point (`agents.control.linear`),
reduce it to the state components the task's `LQRHints` keep, discretise at the control
period with a zero-order hold, solve the discrete Riccati equation, and act as
`a = a0 - K (x - x0)` in the env's normalised action units, clipped to [-1, 1].
`LQRPolicy.predict` has stable-baselines3's signature, so `evaluate_policy` scores it like a
trained model. The command line is `python -m agents.lqr` (agents/lqr.py).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from dynamics import wrap
from envs.checks import Unsupported

from ..common import lagrange_env
from .linear import (
    Controllability,
    LinearModel,
    UncontrollableError,
    _indices,
    discretize,
    linearize,
    require_controllable,
    state_names,
)

__all__ = ["LQRDesign", "LQRPolicy", "UncontrollableError", "design", "dlqr", "linearize"]


def bryson_weights(hints, states: Sequence[str]) -> np.ndarray:
    """Diagonal of Q by Bryson's rule: 1 / scale^2 per kept state component."""
    return np.array([1.0 / hints.scales.get(s, hints.default_scale) ** 2 for s in states])


def start_region(hints, states: Sequence[str]) -> dict[str, float]:
    """The region LQR is expected to hold: the hints' own, else half of each kept
    component's Bryson scale."""
    if hints.region is not None:
        return dict(hints.region)
    return {s: 0.5 * hints.scales.get(s, hints.default_scale) for s in states}


def _weights(W, n: int, name: str) -> np.ndarray:
    W = np.asarray(W, dtype=np.float64)
    if W.ndim == 1:
        if len(W) != n:
            raise ValueError(
                f"{name} must be ({n}, {n}) or a diagonal of length {n}, got {len(W)}."
            )
        W = np.diag(W)
    if W.shape != (n, n):
        raise ValueError(f"{name} must be ({n}, {n}) or a diagonal of length {n}, got {W.shape}.")
    if not np.allclose(W, W.T):
        raise ValueError(f"{name} must be symmetric.")
    return W


def dlqr(Ad, Bd, Q, R) -> tuple[np.ndarray, np.ndarray]:
    """Gain K and cost matrix P of u[k] = -K x[k] minimising sum x'Qx + u'Ru (discrete)."""
    Ad, Bd = np.asarray(Ad, dtype=np.float64), np.asarray(Bd, dtype=np.float64)
    n, m = Bd.shape
    Q, R = _weights(Q, n, "Q"), _weights(R, m, "R")
    if np.linalg.eigvalsh(Q).min() < -1e-12 * max(1.0, np.abs(Q).max()):
        raise ValueError("Q must be positive semi-definite.")
    if np.linalg.eigvalsh(R).min() <= 0:
        raise ValueError("R must be positive definite.")
    P = scipy.linalg.solve_discrete_are(Ad, Bd, Q, R)
    K = np.linalg.solve(R + Bd.T @ P @ Bd, Bd.T @ P @ Ad)
    return K, P


@dataclass(frozen=True)
class LQRDesign:
    """Everything about one LQR design: model, discretisation, gain, eigenvalues."""

    linear: LinearModel
    dt: float
    Ad: np.ndarray
    Bd: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    K: np.ndarray  # (m, n): du = -K dx on `linear.states`, in the units of B's columns
    P: np.ndarray
    controllability: Controllability

    @property
    def open_loop_eigenvalues(self) -> np.ndarray:
        """Eigenvalues of the continuous A, 1/s."""
        return np.linalg.eigvals(self.linear.A)

    @property
    def closed_loop_eigenvalues(self) -> np.ndarray:
        """Eigenvalues of Ad - Bd K (discrete; inside the unit circle when stable)."""
        return np.linalg.eigvals(self.Ad - self.Bd @ self.K)

    @property
    def closed_loop_rates(self) -> np.ndarray:
        """The closed-loop eigenvalues as continuous rates log(z) / dt, 1/s."""
        return np.log(self.closed_loop_eigenvalues.astype(complex)) / self.dt


def warn_unless_equilibrium(system, lin: LinearModel, task: str) -> None:
    """RuntimeWarning naming the kept state whose rate is not zero at the operating point:
    LQR there regulates towards a state the system cannot rest in (a cart's x at a speed of
    1 m/s), and its success is then no statement about the task. The tolerance is 1e-6 of
    the size of the linear terms at that point (round-off of a true equilibrium is ~1e-15)."""
    f = system.state_derivative(0.0, lin.x0, lin.u0)[lin.index]
    scale = 1.0 + np.abs(lin.A) @ np.abs(lin.x0[lin.index]) + np.abs(lin.B) @ np.abs(lin.u0)
    off = np.abs(f) > 1e-6 * scale
    if off.any():
        i = int(np.argmax(np.abs(f) / scale))
        warnings.warn(
            f"LQR on task {task!r}: the operating point is not an equilibrium: "
            f"d{lin.states[i]}/dt = {f[i]:.6g} there, not 0 (residual of the kept states "
            f"{dict(zip(lin.states, np.round(f, 9).tolist()))}); the design regulates towards "
            "a state the system cannot rest in. Give an equilibrium in `operating_point`, or "
            f"leave {lin.states[i]!r} out of LQRHints.states where it may drift.",
            RuntimeWarning,
            stacklevel=3,
        )


def design(lin: LinearModel, dt: float, Q, R, rtol: float = 1e-9) -> LQRDesign:
    """Controllability check, ZOH discretisation at dt and the discrete LQR gain."""
    c = require_controllable(lin, rtol)
    Ad, Bd = discretize(lin.A, lin.B, dt)
    K, P = dlqr(Ad, Bd, Q, R)
    n, m = lin.B.shape
    return LQRDesign(lin, float(dt), Ad, Bd, _weights(Q, n, "Q"), _weights(R, m, "R"), K, P, c)


def refuse_time_dependent(env, agent: str) -> None:
    """ValueError when the env's dynamics depend on time explicitly: an agent designed on
    the dynamics at one time (a linearisation, a plan from t = 0) would be silently wrong."""
    if env.plant.time_dependent:
        raise Unsupported(
            f"{agent} designs on the dynamics at one time, and task {env.task.name!r} is "
            f"time-dependent ({env.system.name}'s accelerations change with t at fixed "
            "state: a prescribed motion or drive), so its answer would be wrong; this agent "
            "does not support time-dependent systems (train an RL agent on the env instead)."
        )


class LQRPolicy:
    """u = u0 - K (x - x0), K from the linearisation at the task's operating point.

    Works in the env's normalised action units: B is taken through the env's action
    scaling, so R weighs actions in [-1, 1] and saturation is the clip to [-1, 1].
    The operating point (and so the gain) follows the goal encoded in each observation;
    gains are cached per operating point. `predict` has stable-baselines3's signature.

    env: a Lagrange env (gymnasium.make or its native vector env). Q, R and states
    override the task's `LQRHints`: Q a diagonal or matrix over `states`, R over actions.
    """

    def __init__(self, env, Q=None, R=None, states: Sequence[str] | None = None):
        self.env = lagrange_env(env)
        self.config = self.env.task.lqr
        self.system = self.env.system
        self.dt = float(self.env.control_period)
        names = state_names(self.system)
        self.states = tuple(states) if states is not None else self.config.states or names
        _indices(names, self.states)  # validates the names
        refuse_time_dependent(self.env, "LQR")
        self.env.plant.require_observed("LQR", self.states)
        self.Q = Q if Q is not None else bryson_weights(self.config, self.states)
        n_a = self.env.action_space.shape[-1]
        self.R = R if R is not None else np.broadcast_to(self.config.R, (n_a,)).astype(float)
        self._S = self._action_matrix(n_a)
        self._n = self.system.n_q
        self._periodic = np.asarray(self.env.periodic, dtype=bool)
        self._designs: dict[bytes, LQRDesign] = {}

    def _action_matrix(self, n_a: int) -> np.ndarray:
        """S (n_u, n_a) with u = u(0) + S a: the env's action scaling, checked to be affine
        (asymmetric input limits shift u(0))."""
        zero = self.env.action_to_input(np.zeros(n_a))
        S = (self.env.action_to_input(np.eye(n_a)) - zero).T
        probe = np.linspace(-0.9, 0.7, n_a)
        if not np.allclose(zero + S @ probe, self.env.action_to_input(probe)):
            raise ValueError("LQRPolicy needs an action scaling u = u0 + S a (affine in a).")
        return S

    def design(self, x0=None, u0=None) -> LQRDesign:
        """The LQR design at (x0, u0), default the env's current operating point; B is in
        action units (columns = action components)."""
        if x0 is None:
            x0, u0 = self.env.operating_point()
        x0, u0 = np.asarray(x0, dtype=np.float64), np.asarray(u0, dtype=np.float64)
        key = x0.tobytes() + u0.tobytes()
        d = self._designs.get(key)
        if d is None:
            try:
                lin = linearize(self.system, x0, u0, self.states)
            except ValueError as exc:
                if not self.system.n_c:
                    raise
                raise Unsupported(
                    f"LQR on {list(self.states)} of task {self.env.task.name!r}: {exc} The "
                    f"constraints of {self.system.name} tie the dropped components to the kept "
                    "ones, so no exact cut of the full linearisation exists; reduce it on the "
                    "constraint manifold instead (the task's heuristic baseline, if declared)."
                ) from exc
            warn_unless_equilibrium(self.system, lin, self.env.task.name)
            lin = LinearModel(
                lin.A, lin.B @ self._S, x0, u0, lin.states, _action_names(self), lin.index
            )
            d = design(lin, self.dt, self.Q, self.R)
            if len(self._designs) >= 4096:
                self._designs.clear()
            self._designs[key] = d
        return d

    def error(self, x, x0) -> np.ndarray:
        """x - x0 with the angle errors wrapped to [-pi, pi)."""
        dx = np.asarray(x, dtype=np.float64) - x0
        q = dx[..., : self._n]
        q[..., self._periodic] = wrap(q[..., self._periodic])
        return dx

    def cost_to_go(self, x, x0, u0) -> np.ndarray:
        """dx' P dx of states x (N, n_x) about each row's operating point (the value of the
        infinite-horizon LQR problem, unsaturated)."""
        x, x0, u0 = np.atleast_2d(x), np.atleast_2d(x0), np.atleast_2d(u0)
        return self.cost_of(x, x0, self.designs(x0, u0))

    def cost_of(self, x, x0, designs: list[LQRDesign]) -> np.ndarray:
        """dx' P dx of states x (N, n_x) about x0 (N, n_x) with `designs`: one for every row
        or one per row (numpy's matmul over a stack of contiguous rows makes the same BLAS
        call per row as the product of that row alone, so stacking changes no result)."""
        e = np.ascontiguousarray(self.error(x, x0)[:, designs[0].linear.index])
        P = designs[0].P if len(designs) == 1 else np.stack([d.P for d in designs])
        return (e[:, None, :] @ P @ e[:, :, None])[:, 0, 0]  # e' P e, row by row

    def act(self, x, x0, u0) -> np.ndarray:
        """Normalised actions for physical states x (batched), clipped to [-1, 1]."""
        x, x0, u0 = np.atleast_2d(x), np.atleast_2d(x0), np.atleast_2d(u0)
        designs = self.designs(x0, u0)
        e = np.ascontiguousarray(self.error(x, x0)[:, designs[0].linear.index])
        K = designs[0].K if len(designs) == 1 else np.stack([d.K for d in designs])
        a = self.env.input_to_action(u0).astype(np.float64)
        return np.clip(a - (K @ e[:, :, None])[:, :, 0], -1.0, 1.0)  # K e, as cost_of

    def designs(self, x0, u0) -> list[LQRDesign]:
        """The designs for the rows' operating points: one where every row has the same (a
        fixed operating point, the common case), else one per row. All are made on
        `self.states`, so their `linear.index` is the same."""
        if len(x0) == 1 or ((x0 == x0[0]).all() and (u0 == u0[0]).all()):
            return [self.design(x0[0], u0[0])]
        return [self.design(a, b) for a, b in zip(x0, u0)]

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        """stable-baselines3's interface: (action, None) for one or a batch of observations."""
        obs = np.asarray(observation, dtype=np.float64)
        flat = obs.reshape(-1, obs.shape[-1])
        x = self.env.state_from_observation(flat)
        x0, u0 = self.env.operating_point(flat)
        a = self.act(x, x0, u0).astype(np.float32)
        return a.reshape(obs.shape[:-1] + a.shape[-1:]), None


def _action_names(policy: LQRPolicy) -> tuple[str, ...]:
    inputs = policy.system.inputs
    return tuple(inputs[int(np.argmax(np.abs(c)))] for c in policy._S.T)
