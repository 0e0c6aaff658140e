"""LQR from the exact linearisation of an environment's equations of motion.

The chain: linearise the compiled `System` at the task's operating point (symbolic Jacobians),
optionally reduce to the state components that matter (e.g. drop the rolling disk's cyclic
coordinates), check controllability, discretise at the control period with a zero-order hold,
solve the discrete Riccati equation, and act as `a = a0 - K (x - x0)` in the env's normalised
action units, clipped to [-1, 1]. `LQRPolicy.predict` has stable-baselines3's signature, so
`evaluate_policy` scores it like a trained model.

    python -m agents.lqr Lagrange/Acrobot-v0 --episodes 100 --plot acrobot_lqr.png
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
import scipy.signal

from .common import atomic_path

# ---------------------------------------------------------------------------------------
# Linearisation and reduction


def state_names(system) -> tuple[str, ...]:
    """Names of the state components [q, qdot]: the coordinates, then '<name>_dot'."""
    return tuple(system.coordinates) + tuple(f"{c}_dot" for c in system.coordinates)


@dataclass(frozen=True)
class LinearModel:
    """d(dx)/dt = A dx + B du about (x0, u0), on the state components `states`."""

    A: np.ndarray
    B: np.ndarray
    x0: np.ndarray  # full physical state of the operating point, (2n,)
    u0: np.ndarray  # model inputs holding it, (n_u,)
    states: tuple[str, ...]  # names of the kept state components (rows of A)
    inputs: tuple[str, ...]  # names of the columns of B
    index: np.ndarray = field(repr=False)  # positions of `states` in the full state


def _indices(names: Sequence[str], keep: Sequence[str] | None) -> np.ndarray:
    if keep is None:
        return np.arange(len(names))
    unknown = [k for k in keep if k not in names]
    if unknown:
        raise ValueError(f"Unknown state components {unknown}. Known: {', '.join(names)}.")
    if len(set(keep)) != len(keep):
        raise ValueError(f"State components repeated in {list(keep)}.")
    return np.array([names.index(k) for k in keep])


def linearize(system, x0, u0, keep: Sequence[str] | None = None, t: float = 0.0) -> LinearModel:
    """Exact linearisation of `system` at (x0, u0), reduced to the state components `keep`.

    Dropping components is exact only if none of them drives a kept one at this operating
    point (true of cyclic coordinates and of rates fixed by the constraints); otherwise this
    raises ValueError naming the coupling. `keep` names come from `state_names(system)`.
    """
    names = state_names(system)
    x0 = np.asarray(x0, dtype=np.float64)
    u0 = np.zeros(system.n_u) if u0 is None else np.asarray(u0, dtype=np.float64)
    A, B = system.linearize(x0, u0, t)
    idx = _indices(names, keep)
    dropped = np.setdiff1d(np.arange(len(names)), idx)
    coupling = np.abs(A[np.ix_(idx, dropped)])
    scale = max(np.abs(A).max(), 1.0)
    if coupling.size and coupling.max() > 1e-10 * scale:
        i, j = np.unravel_index(np.argmax(coupling), coupling.shape)
        raise ValueError(
            f"Cannot drop {names[dropped[j]]!r}: it drives {names[idx[i]]!r} "
            f"(dA = {A[idx[i], dropped[j]]:.3g}) at this operating point."
        )
    return LinearModel(
        A=A[np.ix_(idx, idx)],
        B=B[idx],
        x0=x0,
        u0=u0,
        states=tuple(names[i] for i in idx),
        inputs=tuple(system.inputs),
        index=idx,
    )


# ---------------------------------------------------------------------------------------
# Controllability


class UncontrollableError(ValueError):
    """The linearised pair (A, B) has modes the inputs cannot reach."""


@dataclass(frozen=True)
class Controllability:
    """Controllability of (A, B).

    rank: numerical rank of [B, AB, ..., A^(n-1) B] (singular values above rtol * largest).
    condition: largest / smallest singular value of that matrix after scaling each state
        and input to unit norm (how hard the weakest direction is to reach; inf if rank < n).
    margin: min over eigenvalues lambda of A of the smallest singular value of
        [A - lambda I, B], relative to the norm of [A, B] (PBH test: 0 for a mode that
        cannot be reached; a distance-to-uncontrollability figure otherwise).
    unreachable: descriptions of the modes that cannot be reached (empty if controllable).
    """

    n: int
    rank: int
    condition: float
    margin: float
    unreachable: tuple[str, ...]

    @property
    def controllable(self) -> bool:
        return self.rank == self.n and not self.unreachable


def _mode_text(value: complex, vector: np.ndarray, states: Sequence[str]) -> str:
    w = np.abs(vector) / np.abs(vector).max()
    parts = [f"{states[i]} {w[i]:.2f}" for i in np.argsort(-w) if w[i] > 0.05]
    ev = f"{value.real:.4g}" if abs(value.imag) < 1e-12 else f"{value:.4g}"
    return f"eigenvalue {ev} (mode along {', '.join(parts)})"


def controllability(
    A: np.ndarray, B: np.ndarray, states: Sequence[str] | None = None, rtol: float = 1e-9
) -> Controllability:
    """Rank, conditioning and the unreachable modes (PBH test) of the pair (A, B)."""
    A = np.atleast_2d(np.asarray(A, dtype=np.float64))
    B = np.asarray(B, dtype=np.float64)
    n = A.shape[0]
    if A.shape != (n, n):
        raise ValueError(f"A must be square, got shape {A.shape}.")
    if B.ndim != 2 or B.shape[0] != n:
        raise ValueError(f"B must have shape ({n}, m) to match A, got {B.shape}.")
    states = tuple(states) if states is not None else tuple(f"x{i}" for i in range(n))
    # scale states and inputs so the figures do not depend on units
    d = np.linalg.norm(np.hstack([A, B]), axis=1)
    d[d == 0] = 1.0
    e = np.linalg.norm(B, axis=0)
    e[e == 0] = 1.0
    As, Bs = A / d[:, None] * d[None, :], B / d[:, None] / e[None, :]
    blocks = [Bs]
    for _ in range(n - 1):
        blocks.append(As @ blocks[-1])
    sv = np.linalg.svd(np.hstack(blocks), compute_uv=False)
    rank = int(np.sum(sv > rtol * sv[0])) if sv[0] > 0 else 0
    condition = float(sv[0] / sv[n - 1]) if rank == n else float("inf")

    norm = max(np.linalg.norm(np.hstack([As, Bs]), 2), 1e-300)
    values, left = scipy.linalg.eig(As, left=True, right=False)
    margin, unreachable = np.inf, []
    for k, lam in enumerate(values):
        M = np.hstack([As - lam * np.eye(n), Bs])
        s_min = np.linalg.svd(M, compute_uv=False)[-1] / norm
        margin = min(margin, s_min)
        if s_min <= rtol:
            # left eigenvector in the scaled coordinates -> physical state components
            unreachable.append(_mode_text(lam, left[:, k] / d, states))
    return Controllability(n, rank, condition, float(margin), tuple(dict.fromkeys(unreachable)))


def require_controllable(lin: LinearModel, rtol: float = 1e-9) -> Controllability:
    """`controllability` of a LinearModel; UncontrollableError naming the unreachable modes."""
    c = controllability(lin.A, lin.B, lin.states, rtol)
    if not c.controllable:
        modes = "; ".join(c.unreachable) or f"rank {c.rank} < {c.n}"
        raise UncontrollableError(
            f"(A, B) is not controllable from inputs {', '.join(lin.inputs)}: "
            f"controllability rank {c.rank} of {c.n}; unreachable: {modes}."
        )
    return c


# ---------------------------------------------------------------------------------------
# Discretisation and the Riccati equation


def discretize(A: np.ndarray, B: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Zero-order-hold discretisation: x[k+1] = Ad x[k] + Bd u[k] with u held over dt."""
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a positive finite number, got {dt}.")
    n, m = np.shape(B)
    Ad, Bd, *_ = scipy.signal.cont2discrete((A, B, np.eye(n), np.zeros((n, m))), dt, "zoh")
    return Ad, Bd


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


def design(lin: LinearModel, dt: float, Q, R, rtol: float = 1e-9) -> LQRDesign:
    """Controllability check, ZOH discretisation at dt and the discrete LQR gain."""
    c = require_controllable(lin, rtol)
    Ad, Bd = discretize(lin.A, lin.B, dt)
    K, P = dlqr(Ad, Bd, Q, R)
    n, m = lin.B.shape
    return LQRDesign(lin, float(dt), Ad, Bd, _weights(Q, n, "Q"), _weights(R, m, "R"), K, P, c)


# ---------------------------------------------------------------------------------------
# Per-environment choices


@dataclass(frozen=True)
class EnvConfig:
    """LQR choices for one environment.

    states: the reduced state LQR regulates (None: the full state [q, qdot]).
    scales: Bryson's rule, Q = diag(1 / scale^2): the error in each kept state component
        that costs as much as a full-scale action (names absent here get `default_scale`).
    R: weight of the normalised action (1 / acceptable action^2); scalar or per component.
    region: half-widths of the uniform perturbation of the operating point from which the
        closed loop is evaluated (state component name -> half-width, SI units).
    """

    states: tuple[str, ...] | None = None
    scales: dict[str, float] = field(default_factory=dict)
    default_scale: float = 1.0
    R: float | tuple[float, ...] = 1.0
    region: dict[str, float] = field(default_factory=dict)

    def Q(self, states: Sequence[str]) -> np.ndarray:
        return np.array([1.0 / self.scales.get(s, self.default_scale) ** 2 for s in states])


CONFIGS: dict[str, EnvConfig] = {
    "Lagrange/TwoLinkArm-v0": EnvConfig(
        scales={"theta1": 0.05, "theta2": 0.05},
        region={"theta1": 0.3, "theta2": 0.3, "theta1_dot": 0.5, "theta2_dot": 0.5},
    ),
    "Lagrange/Acrobot-v0": EnvConfig(
        default_scale=0.1,
        region={"theta1": 0.01, "theta2": 0.01, "theta1_dot": 0.02, "theta2_dot": 0.02},
    ),
    "Lagrange/RollingDisk-v0": EnvConfig(
        # the cyclic x, z, psi and the constrained x', z' dropped (see disk_stability)
        states=("theta", "phi", "theta_dot", "phi_dot", "psi_dot"),
        scales={"theta": 0.05, "phi": 1.0, "psi_dot": 0.3},
        region={"theta": 0.02, "phi": 0.2, "theta_dot": 0.1, "phi_dot": 0.1, "psi_dot": 0.5},
    ),
    "Lagrange/BeadOnRod-v0": EnvConfig(
        scales={"r": 0.1, "phi": 0.2, "r_dot": 0.1},
        region={"r": 0.1, "phi": 0.05, "r_dot": 0.1, "phi_dot": 0.1},
    ),
    "Lagrange/CrankSlider-v0": EnvConfig(
        scales={"theta": 0.05},
        region={"theta": 0.2, "theta_dot": 0.5},
    ),
}
"""Default LQR choices by environment id (others: the full state, unit scales, R = 1).

Measured with `python -m agents.lqr ENV_ID --measure-region` (seed 0, 100 episodes): the
largest multiple of each region with >= 99 % success is 12 (arm: any angles, rates up to
6 rad/s), 1.75 (acrobot: 0.0175 rad, 0.035 rad/s; other weights, from Q = I to R = 100 and
Q on the slow unstable mode, measured no better: 85-93 % at 2x. The basin is a thin slab, not
a small ball: no 3 N*m controller recovers once the slow unstable mode (2.7 1/s, the arm
leaning as a whole) exceeds |w'B|/lam, which half the box crosses at 16x
(tests/agents/test_lqr.py); along other directions it is wide: LQR recovers 99 % of
random states with dx' P dx = 500, up to 0.37 rad and 2 rad/s, the swing-up's hand-over
level), 1.6 (disk: 0.03 rad lean; its failures
are at commanded speeds below the self-stable 0.99 m/s, where the 0.1 N*m steering torque
is weak), 3.5 (bead) and 32 (crank: any angle).
"""


def config_for(env_id: str | None) -> EnvConfig:
    """The default `EnvConfig` of an environment id (a neutral one for unknown ids)."""
    return CONFIGS.get(env_id, EnvConfig()) if env_id else EnvConfig()


# ---------------------------------------------------------------------------------------
# The policy


def _env_id(env) -> str | None:
    spec = getattr(env, "spec", None) or getattr(getattr(env, "unwrapped", None), "spec", None)
    return getattr(spec, "id", None)


class LQRPolicy:
    """u = u0 - K (x - x0), K from the linearisation at the task's operating point.

    Works in the env's normalised action units: B is taken through the env's action
    scaling, so R weighs actions in [-1, 1] and saturation is the clip to [-1, 1].
    The operating point (and so the gain) follows the goal encoded in each observation;
    gains are cached per operating point. `predict` has stable-baselines3's signature.

    env: a Lagrange env (gymnasium.make or its native vector env). Q, R override the
    per-env defaults (`CONFIGS`): Q a diagonal or matrix over `states`, R over actions.
    """

    def __init__(self, env, Q=None, R=None, states: Sequence[str] | None = None):
        self.env = env.unwrapped if hasattr(env, "unwrapped") else env
        self.config = config_for(_env_id(env))
        self.system = self.env.system
        self.dt = float(self.env.control_period)
        names = state_names(self.system)
        self.states = tuple(states) if states is not None else self.config.states or names
        _indices(names, self.states)  # validates the names
        self.Q = Q if Q is not None else self.config.Q(self.states)
        n_a = self.env.action_space.shape[-1]
        self.R = R if R is not None else np.broadcast_to(self.config.R, (n_a,)).astype(float)
        self._S = self._action_matrix(n_a)
        self._n = self.system.n_q
        self._periodic = np.asarray(self.env.periodic, dtype=bool)
        self._designs: dict[bytes, LQRDesign] = {}

    def _action_matrix(self, n_a: int) -> np.ndarray:
        """S (n_u, n_a) with u = S a: the env's action scaling, checked to be linear."""
        zero = self.env.action_to_input(np.zeros(n_a))
        S = (self.env.action_to_input(np.eye(n_a)) - zero).T
        probe = np.linspace(-0.9, 0.7, n_a)
        if np.abs(zero).max() > 0 or not np.allclose(S @ probe, self.env.action_to_input(probe)):
            raise ValueError("LQRPolicy needs an action scaling u = S a (linear in the action).")
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
            lin = linearize(self.system, x0, u0, self.states)
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
        q[..., self._periodic] = (q[..., self._periodic] + np.pi) % (2 * np.pi) - np.pi
        return dx

    def act(self, x, x0, u0) -> np.ndarray:
        """Normalised actions for physical states x (batched), clipped to [-1, 1]."""
        x, x0, u0 = np.atleast_2d(x), np.atleast_2d(x0), np.atleast_2d(u0)
        dx = self.error(x, x0)
        a = self.env.input_to_action(u0).astype(np.float64)
        for i in range(len(x)):
            d = self.design(x0[i], u0[i])
            a[i] -= d.K @ dx[i, d.linear.index]
        return np.clip(a, -1.0, 1.0)

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


# ---------------------------------------------------------------------------------------
# Closed-loop evaluation from a region around the operating point


@dataclass(frozen=True)
class ClosedLoop:
    """Outcome of `evaluate_near`: per-episode returns, success at the episode's end, and
    the perturbation region (state component -> half-width) the starts were drawn from."""

    returns: np.ndarray
    success: np.ndarray
    region: dict[str, float]

    @property
    def success_rate(self) -> float:
        return float(np.mean(self.success))


def perturbed_starts(vec, region: dict[str, float], rng: np.random.Generator) -> np.ndarray:
    """Operating points of the vector env's current goals plus uniform perturbations of
    half-width region[name] in each named state component (physical units)."""
    names = state_names(vec.system)
    x0, _ = vec.operating_point()
    x = np.array(x0, dtype=np.float64)
    for name, width in region.items():
        x[:, _indices(names, [name])[0]] += rng.uniform(-width, width, len(x))
    return x


def evaluate_near(
    env_id: str,
    policy=None,
    episodes: int = 100,
    seed: int = 0,
    region: dict[str, float] | None = None,
    scale: float = 1.0,
    **env_kwargs,
) -> ClosedLoop:
    """Run `episodes` seeded episodes in parallel (the native vector env), each started
    at its goal's operating point perturbed uniformly within `scale` x `region` (default:
    the env's `CONFIGS` region). `policy`: an object with SB3's `predict` built for the
    vector env, a callable vec -> such an object, or None for `LQRPolicy`. An episode
    succeeds if `info["is_success"]` holds at its last step."""
    import gymnasium as gym

    vec = gym.make_vec(
        env_id, num_envs=episodes, vectorization_mode="vector_entry_point", **env_kwargs
    )
    try:
        region = dict(config_for(env_id).region if region is None else region)
        region = {k: scale * v for k, v in region.items()}
        vec.reset(seed=seed)  # draws each copy's goal
        goals = vec.unwrapped.goal
        starts = perturbed_starts(vec.unwrapped, region, np.random.default_rng(seed))
        obs, _ = vec.reset(seed=seed, options={"state": starts, "goal": goals})
        if policy is None:
            policy = LQRPolicy(vec)
        elif isinstance(policy, type) or not hasattr(policy, "predict"):
            policy = policy(vec)
        returns = np.zeros(episodes)
        success = np.zeros(episodes, dtype=bool)
        running = np.ones(episodes, dtype=bool)
        while running.any():
            action, _ = policy.predict(obs, deterministic=True)
            obs, reward, terminated, truncated, info = vec.step(action)
            returns += np.where(running, reward, 0.0)
            done = running & (terminated | truncated)
            success[done] = info["is_success"][done]
            running &= ~done
        return ClosedLoop(returns, success, region)
    finally:
        vec.close()


class ZeroPolicy:
    """The zero action (no torque): the baseline LQR must beat near the operating point."""

    def __init__(self, env):
        space = getattr(env, "single_action_space", None) or env.action_space
        self.shape = space.shape

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        obs = np.asarray(observation)
        return np.zeros(obs.shape[:-1] + self.shape[-1:], dtype=np.float32), None


def largest_region(
    env_id: str, policy=None, target: float = 0.99, episodes: int = 100, seed: int = 0
) -> tuple[float, ClosedLoop]:
    """The largest multiple of the env's `CONFIGS` region (to 1/16 of a doubling) from
    which the closed loop still reaches `target` success, and its evaluation there."""

    def ok(s: float) -> ClosedLoop | None:
        r = evaluate_near(env_id, policy, episodes, seed, scale=s)
        return r if r.success_rate >= target else None

    lo, best = 0.0, None
    hi = 1.0
    while (r := ok(hi)) is not None and hi < 64:
        lo, best, hi = hi, r, 2 * hi
    if best is None or hi < 64:
        for _ in range(4):
            mid = (lo + hi) / 2
            if (r := ok(mid)) is not None:
                lo, best = mid, r
            else:
                hi = mid
    if best is None:
        raise RuntimeError(f"{env_id}: LQR below {target:.0%} success even at 1/16 of the region.")
    return lo, best


# ---------------------------------------------------------------------------------------
# Command line


def save_figure(fig, path: str) -> None:
    """fig.savefig to `path` atomically (temporary file in the same directory + replace)."""
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120)


def describe(d: LQRDesign) -> str:
    """A, B, eigenvalues, controllability and gain of a design, as text."""
    lin = d.linear

    def mat(M, rows, cols):
        head = " " * 12 + "".join(f"{c:>12.11}" for c in cols)
        body = [f"{r:>12.11}" + "".join(f"{v:12.4g}" for v in row) for r, row in zip(rows, M)]
        return "\n".join([head, *body])

    c = d.controllability
    ev = lambda z: "  ".join(f"{v:.4g}" for v in sorted(z, key=lambda v: (v.real, v.imag)))  # noqa: E731
    return "\n".join(
        [
            f"operating point x0 = {np.array2string(lin.x0, precision=4)}, "
            f"u0 = {np.array2string(lin.u0, precision=4)}",
            "A (continuous, on the regulated state):",
            mat(lin.A, lin.states, lin.states),
            "B (per unit of normalised action):",
            mat(lin.B, lin.states, lin.inputs),
            f"open-loop eigenvalues (1/s): {ev(d.open_loop_eigenvalues)}",
            f"controllability: rank {c.rank} of {c.n}, condition number {c.condition:.3g}, "
            f"PBH margin {c.margin:.3g}",
            f"discretised with a zero-order hold at dt = {d.dt:g} s; Q diag = "
            f"{np.array2string(np.diag(d.Q), precision=4)}, R diag = "
            f"{np.array2string(np.diag(d.R), precision=4)}",
            "gain K (action = a0 - K dx):",
            mat(d.K, lin.inputs, lin.states),
            "closed-loop |z|: "
            + np.array2string(np.sort(np.abs(d.closed_loop_eigenvalues)), precision=4),
            f"closed-loop rates log(z)/dt (1/s): {ev(d.closed_loop_rates)}",
        ]
    )


def plot_response(env_id: str, path: str, seed: int = 0, Q=None, R=None, **env_kwargs) -> None:
    """The closed-loop response from one perturbed start (errors and actions vs time)."""
    import gymnasium as gym
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    env = gym.make(env_id, **env_kwargs)
    try:
        base = env.unwrapped
        env.reset(seed=seed)
        goal = base.goal
        policy = LQRPolicy(env, Q=Q, R=R)
        region = config_for(env_id).region
        vec_like = _OneRow(base)
        start = perturbed_starts(vec_like, region, np.random.default_rng(seed))[0]
        obs, _ = env.reset(seed=seed, options={"state": start, "goal": goal})
        x0, u0 = base.operating_point()
        d = policy.design(x0, u0)
        errors, actions, success = [policy.error(base.state, x0)[d.linear.index]], [], []
        done = False
        while not done:
            a, _ = policy.predict(obs)
            obs, _, terminated, truncated, info = env.step(a)
            errors.append(policy.error(info["state"], x0)[d.linear.index])
            actions.append(a)
            success.append(info["is_success"])
            done = terminated or truncated
    finally:
        env.close()
    t = base.control_period * np.arange(len(errors))
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    ax1.plot(t, np.array(errors), label=list(d.linear.states))
    ax1.set_ylabel("x - x0 (SI; angles wrapped)")
    ax1.set_title(
        f"{env_id}: LQR from a perturbed start (seed {seed}); success at end: {success[-1]}"
    )
    ax1.legend(fontsize=8, ncol=3)
    ax2.step(t[1:], np.array(actions), where="pre", label=list(d.linear.inputs))
    ax2.set_ylabel("normalised action")
    ax2.set_xlabel("time (s)")
    ax2.set_ylim(-1.1, 1.1)
    ax2.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)


class _OneRow:
    """A single env seen as a vector env of one copy (for `perturbed_starts`)."""

    def __init__(self, env):
        self.system = env.system
        self._env = env

    def operating_point(self):
        x0, u0 = self._env.operating_point()
        return x0[None], u0[None]


def _floats(text: str) -> list[float]:
    try:
        return [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated numbers, got {text!r}"
        ) from None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m agents.lqr",
        description="LQR at an environment's operating point: prints A, B, eigenvalues, "
        "controllability and the gain, then scores the closed loop over seeded episodes "
        "started near the operating point (and zero torque for comparison).",
    )
    parser.add_argument("env_id", help="e.g. Lagrange/Acrobot-v0")
    parser.add_argument("--episodes", type=int, default=100, help="seeded episodes (100)")
    parser.add_argument("--seed", type=int, default=0, help="first seed (0)")
    parser.add_argument("--scale", type=float, default=1.0, help="multiple of the start region")
    parser.add_argument("--plot", metavar="FILE", help="save the closed-loop response here")
    parser.add_argument(
        "--q", type=_floats, metavar="W,W,...", help="diagonal of Q over the regulated state"
    )
    parser.add_argument("--r", type=_floats, metavar="W,...", help="diagonal of R over actions")
    parser.add_argument(
        "--measure-region",
        action="store_true",
        help="also search the largest multiple of the region with >= 99%% success",
    )
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error(f"--episodes must be at least 1, got {args.episodes}")
    if not (np.isfinite(args.scale) and args.scale >= 0):
        parser.error(f"--scale must be a non-negative number, got {args.scale}")
    import gymnasium as gym

    import envs

    if args.env_id not in gym.registry:
        import difflib

        close = difflib.get_close_matches(args.env_id, envs.ENV_IDS, n=1)
        hint = f" Did you mean {close[0]!r}?" if close else ""
        parser.error(f"unknown environment {args.env_id!r}.{hint} Known: {', '.join(envs.ENV_IDS)}")
    env = gym.make(args.env_id)
    env.reset(seed=args.seed)
    try:
        policy = LQRPolicy(env, Q=args.q, R=args.r)
        print(f"{args.env_id}: LQR at the operating point of the goal drawn with seed {args.seed}")
        print(describe(policy.design()))
    except UncontrollableError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    except ValueError as e:
        parser.error(str(e))
    finally:
        env.close()
    cfg = config_for(args.env_id)
    region = {k: args.scale * v for k, v in cfg.region.items()}
    print(f"\nstarts: operating point + uniform perturbation within +- {region}")
    lqr_policy = lambda vec: LQRPolicy(vec, Q=args.q, R=args.r)  # noqa: E731
    for name, pol in (("LQR", lqr_policy), ("zero torque", ZeroPolicy)):
        r = evaluate_near(args.env_id, pol, args.episodes, args.seed, scale=args.scale)
        print(
            f"{name:>11}: success {r.success.sum()}/{args.episodes} ({r.success_rate:.0%}), "
            f"return {r.returns.mean():.2f} +- {r.returns.std():.2f}"
        )
    if args.measure_region:
        s, r = largest_region(args.env_id, lqr_policy, episodes=args.episodes, seed=args.seed)
        print(
            f"largest region with >= 99% success: {s:g} x the above "
            f"({ {k: s * v for k, v in cfg.region.items()} }), success {r.success_rate:.0%}"
        )
    if args.plot:
        plot_response(args.env_id, args.plot, args.seed, Q=args.q, R=args.r)
        print(f"saved {args.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
