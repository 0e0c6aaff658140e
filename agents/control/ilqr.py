"""Trajectory optimisation on the derived model: a motion from a start state to the task's
operating point within the env's input limits.

Control-limited iLQR (Tassa, Mansard and Todorov, ICRA 2014) on the env's own discrete
dynamics: x[k+1] = step(x[k], a[k]) is `System.step` with the env's control period,
integrator and substeps, the normalised action a[k] held over each period (zero-order hold)
and boxed in [-action_bound, action_bound]. Every iterate is a rollout of that step, so a
plan is exactly the motion the env produces under its actions (no defect to tolerate), and
only the search direction uses derivatives: each period's Jacobians dx[k+1]/dx[k], da[k] are
the exact derivative of a Runge-Kutta step, chained through the exact continuous Jacobians
`System.linearize` at its stage states (`step_jacobians`: for planning `jacobian_substeps`
RK4 steps per period, an approximation that only steers the search; for tracking the env's
own method and substeps). The cost is

    sum_k dt (a' R a + e' W e) + e_N' P_N e_N,   e = x - x0 (angle errors wrapped),

with R the task's LQR action weight, W its Bryson state weights scaled by `state_weight`
and P_N the same weights scaled by `terminal_weight`, raised tenfold twice while the end
misses the operating point by more than `goal_tolerance` (continuation: a stiff end cost
from the start traps the search in motions that spin a link).

Why hand-written iLQR and not a solver library: direct collocation with scipy's SLSQP
(dense SQP, BFGS Hessian) needed 500+ iterations (30 s) and still missed a 4 s acrobot
swing-up's defects by 4e-4, and scipy's least_squares stalled at infeasible points; an
interior-point solver (IPOPT through cyipopt or CasADi) would add a compiled dependency
and still plan on a discretisation other than the env's. iLQR's Riccati-structured
backward pass costs O(N) per iteration, its box-constrained step per period is a tiny QP
(`box_qp`), and its forward pass is the env's own integrator, batched over line-search step
sizes; the gains of its last backward pass are a time-varying LQR for free.

`plan(env)` plans from the env's current state (or `start`) to its operating point;
`agents.control.tvlqr` tracks a plan; the command line is `python -m agents.plan ENV_ID`
(agents/plan.py).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from dynamics import wrap
from dynamics.checks import real_array

from ..common import lagrange_env
from ..values import Bad, integer, real, short
from .discrete import (  # noqa: F401  (RK4, env_tableau: importable from here as before)
    RK4,
    action_matrix,
    env_step,
    env_tableau,
    rollout,
    step_jacobians,
)

__all__ = [
    "Plan",
    "PlanError",
    "box_qp",
    "env_step",
    "env_tableau",
    "plan",
    "plan_options",
    "rollout",
    "step_jacobians",
]

DEFAULTS = {
    "horizon": 5.0,
    "action_bound": 0.9,
    "state_weight": 1e-3,
    "terminal_weight": 1.0,
    "goal_tolerance": 1e-2,
    "max_iterations": 400,
    "jacobian_substeps": 1,
}
"""Planner options when the task declares none (`Task.hyperparams["plan"]` overrides):
horizon (s); action_bound: the fraction of the env's input limits the plan may use (the
rest is the tracking controller's headroom); state_weight, terminal_weight: the cost's
scales (see the module docstring); max_iterations of iLQR; jacobian_substeps: RK4 steps
per control period in the derivatives used for planning."""


class PlanError(RuntimeError):
    """The planner found no trajectory that ends near the operating point."""


@dataclass(frozen=True)
class Plan:
    """A planned motion on the env's control grid.

    x: (N + 1, 2n) states at the control instants (angles continuous, not wrapped); actions:
    (N, n_a) normalised actions, each held over one control period dt; t: (N + 1,) times, s;
    goal: the operating point x0 (its angles moved by whole turns next to where the plan
    ends); gains: (N, n_a, 2n) iLQR's feedback gains; terminal_error: the largest |x_N - x0|
    component; cost, iterations, seconds: how the solve went.
    """

    t: np.ndarray
    x: np.ndarray
    actions: np.ndarray
    goal: np.ndarray
    dt: float
    gains: np.ndarray
    cost: float
    terminal_error: float
    iterations: int
    seconds: float

    @property
    def steps(self) -> int:
        """Control periods N."""
        return len(self.actions)


MAX_STEPS = 20_000
"""The most control periods a plan may have (each holds a few (2n x 2n) matrices)."""


def _option_rules() -> dict:
    return {
        "horizon": real(0.0, 3600.0, open_low=True),
        "action_bound": real(0.0, 1.0, open_low=True),
        "state_weight": real(0.0, 1e9),
        "terminal_weight": real(0.0, 1e9, open_low=True),
        "goal_tolerance": real(0.0, 1e6, open_low=True),
        "max_iterations": integer(1, 100_000),
        "jacobian_substeps": integer(1, 100),
    }


def plan_options(env, **overrides) -> dict:
    """The planner's options: DEFAULTS, then the task's `hyperparams["plan"]`, then
    `overrides` (None values ignored), each checked; unknown names or bad values raise
    ValueError (one line, naming the option and where it came from)."""
    task = lagrange_env(env).task
    opts = dict(DEFAULTS)
    rules = _option_rules()
    sources = {f"task {task.name!r} (hyperparams['plan'])": task.hyperparams.get("plan", {})}
    sources["the planner's arguments"] = overrides
    for where, source in sources.items():
        for k, v in source.items():
            if k not in DEFAULTS:
                raise ValueError(
                    f"Unknown planner option {k!r} in {where}; known: {', '.join(DEFAULTS)}."
                )
            if v is not None:
                try:
                    opts[k] = rules[k](v)
                except Bad as exc:
                    raise ValueError(
                        f"Planner option {k} in {where} must be {exc}, got {short(v)}."
                    ) from None
    period = float(lagrange_env(env).control_period)
    if opts["horizon"] / period > MAX_STEPS:
        raise ValueError(
            f"Planner option horizon {short(opts['horizon'])} s is more than {MAX_STEPS} "
            f"control periods of {period:g} s."
        )
    return opts


# ---- the box-constrained step of one period --------------------------------------------
def box_qp(H, g, lower, upper, x0=None, iterations: int = 50):
    """min 1/2 x'Hx + g'x subject to lower <= x <= upper (H positive definite): projected
    Newton (Tassa et al. 2014, algorithm 3). Returns (x, free): the solution and the mask
    of components not held at a bound (the feedback acts on those only)."""
    m = len(g)
    x = np.clip(np.zeros(m) if x0 is None else x0, lower, upper)
    free = np.ones(m, dtype=bool)
    for _ in range(iterations):
        grad = g + H @ x
        clamped = ((x <= lower) & (grad > 0)) | ((x >= upper) & (grad < 0))
        free = ~clamped
        if not free.any():
            break
        step = np.zeros(m)
        Hf = H[np.ix_(free, free)]
        step[free] = -np.linalg.solve(Hf, grad[free])
        if np.abs(step).max() < 1e-12:
            break
        value = 0.5 * x @ H @ x + g @ x
        alpha = 1.0
        while alpha > 1e-10:  # Armijo along the projected arc
            xn = np.clip(x + alpha * step, lower, upper)
            if 0.5 * xn @ H @ xn + g @ xn <= value + 0.1 * grad @ (xn - x):
                break
            alpha *= 0.5
        if np.abs(xn - x).max() < 1e-12:
            x = xn
            break
        x = xn
    grad = g + H @ x
    free = ~(((x <= lower + 1e-12) & (grad > 0)) | ((x >= upper - 1e-12) & (grad < 0)))
    return x, free


# ---- iLQR ------------------------------------------------------------------------------
class _Problem:
    """Cost and dynamics of one planning problem (see the module docstring)."""

    def __init__(self, env, start, goal, steps, opts, Q, R):
        self.env, self.system = env, env.system
        self.S = action_matrix(env)
        self.dt = float(env.control_period)
        self.N = steps
        self.start, self.goal = start, goal
        self.bound = float(opts["action_bound"])
        self.jac_substeps = int(opts["jacobian_substeps"])
        self.W = float(opts["state_weight"]) * Q
        self.R = R
        self.P = float(opts["terminal_weight"]) * Q
        self.periodic = np.zeros(self.system.state_size, dtype=bool)
        self.periodic[: self.system.n_q] = np.asarray(env.periodic, dtype=bool)

    def error(self, x):
        e = np.asarray(x, dtype=np.float64) - self.goal
        e[..., self.periodic] = wrap(e[..., self.periodic])
        return e

    def cost(self, X, A):
        """Total cost of trajectories X (..., N + 1, 2n) under actions A (..., N, n_a)."""
        e = self.error(X)
        run = np.einsum("...ki,ij,...kj->...", e[..., :-1, :], self.W, e[..., :-1, :])
        run = run + np.einsum("...ki,ij,...kj->...", A, self.R, A)
        end = np.einsum("...i,ij,...j->...", e[..., -1, :], self.P, e[..., -1, :])
        return self.dt * run + end

    def backward(self, X, A, mu):
        """Gains (k, K) and the expected cost decrease terms, or None if a Q_uu is not
        positive definite at regularisation mu."""
        Fx, Fu = step_jacobians(self.system, X[:-1], A @ self.S.T, self.dt, self.jac_substeps)
        Fu = Fu @ self.S
        N, n_a = A.shape
        e = self.error(X)
        Vx, Vxx = 2 * self.P @ e[-1], 2 * self.P
        k = np.zeros((N, n_a))
        K = np.zeros((N, n_a, X.shape[1]))
        d1 = d2 = 0.0
        lxx, luu = 2 * self.dt * self.W, 2 * self.dt * self.R
        for i in range(N - 1, -1, -1):
            Qx = lxx @ e[i] + Fx[i].T @ Vx
            Qu = luu @ A[i] + Fu[i].T @ Vx
            Qxx = lxx + Fx[i].T @ Vxx @ Fx[i]
            Quu = luu + Fu[i].T @ Vxx @ Fu[i]
            Qux = Fu[i].T @ Vxx @ Fx[i]
            Quu_reg = Quu + mu * np.eye(n_a)
            if np.linalg.eigvalsh(Quu_reg).min() <= 0:
                return None
            lo, hi = -self.bound - A[i], self.bound - A[i]
            ki, free = box_qp(Quu_reg, Qu, lo, hi, k[min(i + 1, N - 1)])
            Ki = np.zeros((n_a, X.shape[1]))
            if free.any():
                Ki[free] = -np.linalg.solve(Quu_reg[np.ix_(free, free)], Qux[free])
            k[i], K[i] = ki, Ki
            d1 += ki @ Qu
            d2 += 0.5 * ki @ Quu @ ki
            Vx = Qx + Ki.T @ Quu @ ki + Ki.T @ Qu + Qux.T @ ki
            Vxx = Qxx + Ki.T @ Quu @ Ki + Ki.T @ Qux + Qux.T @ Ki
            Vxx = 0.5 * (Vxx + Vxx.T)
        return k, K, d1, d2

    def forward(self, X, A, k, K, alphas):
        """Closed-loop rollouts for every step size at once: (costs, X, A) per alpha."""
        B = len(alphas)
        Xn = np.empty((B,) + X.shape)
        An = np.empty((B,) + A.shape)
        Xn[:, 0] = self.start
        for i in range(self.N):
            dx = Xn[:, i] - X[i]
            a = A[i] + alphas[:, None] * k[i] + dx @ K[i].T
            An[:, i] = np.clip(a, -self.bound, self.bound)
            Xn[:, i + 1] = env_step(self.env, Xn[:, i], An[:, i] @ self.S.T, i * self.dt)
        return self.cost(Xn, An), Xn, An


ALPHAS = 0.5 ** np.arange(8)


def ilqr(problem: _Problem, A, max_iterations: int, tolerance: float = 1e-7):
    """Control-limited iLQR from actions A: (X, A, gains, cost, iterations)."""
    X = rollout(problem.env, problem.start, A)
    J = float(problem.cost(X, A))
    mu, K = 1e-6, np.zeros((problem.N, A.shape[1], X.shape[1]))
    it = 0
    while it < max_iterations:
        it += 1
        back = problem.backward(X, A, mu)
        if back is None:
            mu = max(mu * 10, 1e-4)
            continue
        k, K, d1, d2 = back
        costs, Xs, As = problem.forward(X, A, k, K, ALPHAS)
        expected = -(ALPHAS * d1 + ALPHAS**2 * d2)
        ratio = (J - costs) / np.maximum(expected, 1e-300)
        ok = np.flatnonzero(np.isfinite(costs) & ((ratio > 0.1) | (expected <= 0) & (costs < J)))
        if len(ok) == 0:
            mu = max(mu * 10, 1e-4)
            if mu > 1e8:
                break
            continue
        j = ok[0]
        improvement = J - costs[j]
        X, A, J = Xs[j], As[j], float(costs[j])
        mu = max(mu / 10, 1e-9)
        if improvement < tolerance * max(1.0, abs(J)):
            break
    return X, A, K, J, it


def plan(
    env,
    start=None,
    goal=None,
    horizon: float | None = None,
    guess=None,
    strict: bool = True,
    **options,
) -> Plan:
    """A motion of `env`'s system from `start` (default: its current state) to `goal` (a
    full state; default: the env's operating point) in `horizon` seconds, with normalised
    actions within `action_bound`. `guess`: initial actions (N, n_a) or a Plan (its
    actions resampled onto this horizon); default all zero. Other options: see DEFAULTS.
    PlanError if the plan ends farther than `goal_tolerance` from the goal (with `strict`;
    otherwise the plan is returned as it is: see `Plan.terminal_error`)."""
    from .lqr_policy import LQRPolicy

    env = lagrange_env(env)
    opts = plan_options(env, horizon=horizon, **options)
    x_now = np.atleast_2d(env.state)[0]
    start = np.array(x_now if start is None else start, dtype=np.float64)
    if goal is None:
        x0, u0 = (np.atleast_2d(v)[0] for v in env.operating_point())
    else:
        x0 = np.array(goal, dtype=np.float64)
        u0 = np.atleast_2d(env.operating_point(None)[1])[0]
    lqr = LQRPolicy(env)
    d = lqr.design(x0, u0)
    Q = _full(d.Q, d.linear.index, len(x0))
    dt = float(env.control_period)
    steps = max(1, int(round(float(opts["horizon"]) / dt)))
    A = _initial_actions(guess, steps, action_matrix(env).shape[1])
    began, iterations = time.perf_counter(), 0
    for factor in (1.0, 10.0, 100.0):  # continuation: tighten the end once it is reached
        weights = dict(opts, terminal_weight=factor * float(opts["terminal_weight"]))
        problem = _Problem(env, start, x0, steps, weights, Q, np.atleast_2d(d.R))
        A = np.clip(A, -problem.bound, problem.bound)
        X, A, K, J, it = ilqr(problem, A, int(opts["max_iterations"]) - iterations)
        iterations += it
        err = float(np.abs(problem.error(X[-1])).max())
        if err <= float(opts["goal_tolerance"]) or iterations >= int(opts["max_iterations"]):
            break
    seconds = time.perf_counter() - began
    goal_here = x0.copy()
    goal_here[problem.periodic] = X[-1, problem.periodic] - problem.error(X[-1])[problem.periodic]
    result = Plan(
        t=dt * np.arange(steps + 1),
        x=X,
        actions=A,
        goal=goal_here,
        dt=dt,
        gains=K,
        cost=J,
        terminal_error=err,
        iterations=iterations,
        seconds=seconds,
    )
    if strict and err > float(opts["goal_tolerance"]):
        raise PlanError(
            f"The plan of {opts['horizon']} s ends {err:.3g} (largest state component) from "
            f"the operating point, beyond the goal tolerance {opts['goal_tolerance']} after "
            f"{iterations} iterations; try another horizon."
        )
    return result


def _full(M, index, n):
    """A matrix on the kept state components, embedded in the full state (zeros elsewhere)."""
    F = np.zeros((n, n))
    F[np.ix_(index, index)] = M
    return F


def _initial_actions(guess, steps: int, n_a: int) -> np.ndarray:
    if guess is None:
        return np.zeros((steps, n_a))
    a = real_array(guess.actions if isinstance(guess, Plan) else guess, "plan: guess")
    if a.ndim != 2 or a.shape[1] != n_a or len(a) < 1:
        raise ValueError(
            f"plan: guess must be actions of shape (N, {n_a}) (N steps of the env's {n_a} "
            f"normalised inputs) or a Plan, got shape {a.shape}."
        )
    if not np.isfinite(a).all():
        bad = tuple(int(i) for i in np.argwhere(~np.isfinite(a))[0])
        raise ValueError(f"plan: guess must be finite, got {a[bad]} at {bad}.")
    if len(a) == steps:
        return a.copy()
    s, sg = (np.arange(steps) + 0.5) / steps, (np.arange(len(a)) + 0.5) / len(a)
    return np.stack([np.interp(s, sg, a[:, i]) for i in range(n_a)], axis=1)
