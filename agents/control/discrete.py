"""The env's discrete dynamics for planning and tracking: one control period of its
integrator with the normalised action held (zero-order hold), rollouts of it, and its exact
derivative (`step_jacobians`: the derivative of the Runge-Kutta steps, chained through the
exact continuous Jacobians `System.linearize` at the stage states)."""

from __future__ import annotations

import numpy as np

from ..common import lagrange_env


def action_matrix(env) -> np.ndarray:
    """S (n_u, n_a): the model inputs u = S a of normalised actions a."""
    n_a = len(env.plant.actuated)
    return env.action_to_input(np.eye(n_a)).T


# ---- the discrete dynamics and its derivatives -----------------------------------------
RK4 = (
    np.array([[0, 0, 0, 0], [0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 1.0, 0]]),
    np.array([1 / 6, 1 / 3, 1 / 3, 1 / 6]),
    np.array([0, 0.5, 0.5, 1.0]),
)
"""The classical Runge-Kutta tableau (a, b, c)."""


def env_tableau(env) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The Butcher tableau (a, b, c) of the env's integrator (RK4 unless it names another
    of `dynamics.methods`)."""
    method = getattr(env, "integrator", "rk4")
    if method == "rk4":
        return RK4
    from dynamics.methods import METHODS

    t = METHODS[method]
    return t.a, t.b, t.c


def env_step(env, x, u, t=0.0) -> np.ndarray:
    """One control period of the env's own integration (method and substeps), batched:
    the bound plant's step (`envs.plant.Plant.step`)."""
    return env.plant.step(x, u, t)


def rollout(env, start, actions, t0: float = 0.0) -> np.ndarray:
    """States (N + 1, 2n) of the env's own step from `start` under the normalised
    `actions` (N, n_a) held over each control period; batched: starts (B, 2n) and actions
    (B, N, n_a) give (B, N + 1, 2n)."""
    env = lagrange_env(env)
    dt = float(env.control_period)
    actions = np.asarray(actions, dtype=np.float64)
    X = [np.asarray(start, dtype=np.float64)]
    for k in range(actions.shape[-2]):
        X.append(env_step(env, X[-1], env.action_to_input(actions[..., k, :]), t0 + k * dt))
    return np.stack(X, axis=-2)


def step_jacobians(system, X, U, dt: float, substeps: int, t0: float = 0.0, tableau=RK4):
    """Exact derivatives of `substeps` explicit Runge-Kutta steps (Butcher `tableau`
    (a, b, c), default RK4) over each period dt, inputs held: Fx (N, 2n, 2n) =
    dx[k+1]/dx[k] and Fu (N, 2n, n_u) = dx[k+1]/du[k] at the states X (N, 2n) under the
    inputs U (N, n_u), period k starting at t0 + k dt. The stage states are integrated
    batched over the periods; each stage's Jacobian is `system.linearize` there (exact,
    from the symbolic derivatives), chained as the method combines the stages."""
    a, b, c = (np.asarray(v, dtype=np.float64) for v in tableau)
    X, U = np.atleast_2d(X).astype(np.float64), np.atleast_2d(U).astype(np.float64)
    N, n = X.shape
    h = dt / substeps
    Fx = np.broadcast_to(np.eye(n), (N, n, n)).copy()
    Fu = np.zeros((N, n, U.shape[1]))
    x = X.copy()
    t = t0 + dt * np.arange(N)
    for _ in range(substeps):
        ks, dks_x, dks_u = [], [], []
        for i in range(len(b)):
            xs, dxs, dus = x.copy(), Fx.copy(), Fu.copy()
            for j in range(i):
                if a[i, j]:
                    xs += h * a[i, j] * ks[j]
                    dxs += h * a[i, j] * dks_x[j]
                    dus += h * a[i, j] * dks_u[j]
            ks.append(system.state_derivative(t + c[i] * h, xs, U))
            dk_x, dk_u = np.empty_like(Fx), np.empty_like(Fu)
            for r in range(N):
                A, B = system.linearize(xs[r], U[r], t[r] + c[i] * h)
                dk_x[r] = A @ dxs[r]
                dk_u[r] = A @ dus[r] + B
            dks_x.append(dk_x)
            dks_u.append(dk_u)
        x = x + h * sum(w * k for w, k in zip(b, ks))
        Fx = Fx + h * sum(w * d for w, d in zip(b, dks_x))
        Fu = Fu + h * sum(w * d for w, d in zip(b, dks_u))
        t = t + h
    return Fx, Fu
