"""Time-varying LQR along a planned trajectory, handing over to the operating point's LQR.

Along a plan (x_k, a_k) of `agents.plan` the env's step is linearised exactly
(`agents.plan.step_jacobians`: the derivative of its RK4 substeps, through the exact
continuous Jacobians), dx[k+1] = A_k dx[k] + B_k da[k] in normalised action units, and the
discrete Riccati recursion runs backwards from the LQR cost matrix P of the operating
point (the cost LQR pays from the plan's end on):

    K_k = (R + B_k' P_k+1 B_k)^-1 B_k' P_k+1 A_k,   P_k = Q + A_k' P_k+1 (A_k - B_k K_k)

with Q, R the task's LQR weights (`LQRHints`). The action is a_k - K_k (x - x_k) (angle
errors wrapped), clipped to [-1, 1]; after the plan's last step `agents.lqr.LQRPolicy`
takes over.

`PlanPolicy` is the agent (`agents.evaluate` name "plan"): SB3's `predict` over a single or
a vector env. It keeps, per row, the plan it tracks and the step it is at; a row whose
observation is not the state the model predicts from its last observation and action
(a reset, or `episode_start`) starts a new episode and tracks the nominal plan (planned
once per operating point, from the centre of the task's start distribution) from step 0;
TVLQR absorbs the spread of starts. With `replan=True` it plans from each start instead
(warm-started from the nominal plan; the nominal one where that misses the goal).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..common import lagrange_env
from .discrete import action_matrix, env_step, env_tableau, step_jacobians
from .ilqr import Plan, PlanError, plan
from .lqr_policy import LQRPolicy, refuse_time_dependent

__all__ = ["PlanPolicy", "Tracker", "tvlqr"]


@dataclass(frozen=True)
class Tracker:
    """A plan and its time-varying gains K (N, n_a, 2n) over the full state."""

    plan: Plan
    K: np.ndarray
    P0: np.ndarray  # the cost-to-go matrix at the plan's start


def _embed(M: np.ndarray, index: np.ndarray, n: int) -> np.ndarray:
    F = np.zeros((n, n))
    F[np.ix_(index, index)] = M
    return F


def tvlqr(env, p: Plan, u0, lqr: LQRPolicy | None = None) -> Tracker:
    """The time-varying LQR gains along plan `p` to the operating point (p.goal, u0) (see
    the module docstring)."""
    env = lagrange_env(env)
    lqr = lqr if lqr is not None else LQRPolicy(env)
    d = lqr.design(p.goal, u0)
    n = env.system.state_size
    Q = _embed(d.Q, d.linear.index, n)
    R = np.atleast_2d(d.R)
    P = _embed(d.P, d.linear.index, n)
    S = action_matrix(env)
    A, B = step_jacobians(
        env.system,
        p.x[:-1],
        p.actions @ S.T,
        p.dt,
        env.substeps,
        float(p.t[0]),
        env_tableau(env),
    )
    B = B @ S
    K = np.zeros((p.steps,) + (S.shape[1], n))
    for k in range(p.steps - 1, -1, -1):
        BP = B[k].T @ P
        K[k] = np.linalg.solve(R + BP @ B[k], BP @ A[k])
        P = Q + A[k].T @ P @ (A[k] - B[k] @ K[k])
        P = 0.5 * (P + P.T)
    return Tracker(p, K, P)


def start_centre(env) -> np.ndarray | None:
    """The centre of the task's start distribution (None when `start` is a function)."""
    from envs.task import resolve

    plant = env.plant
    if callable(plant.task.start):
        return None
    x = np.zeros(env.system.state_size)
    for name, (lo, hi) in plant.task.start.items():
        x[plant.state_names.index(name)] = (resolve(lo, plant.p) + resolve(hi, plant.p)) / 2
    return x


class PlanPolicy:
    """Trajectory optimisation + time-varying LQR + LQR: plan from each episode's start to
    the operating point, track the plan, hold the operating point.

    env: a Lagrange env (single or native vector). replan: plan from every new start (True;
    seconds each) or track the nominal plan from every start (False). Other keyword
    arguments are planner options (`agents.plan.DEFAULTS`). `predict` has stable-
    baselines3's signature; `episode_start` (if given) marks rows that begin an episode.
    """

    RESET_TOLERANCE = 1e-3
    """A row whose state differs from the model's prediction by more than this (rad, m,
    or per second; float32 observations round at ~1e-6) began a new episode."""

    def __init__(self, env, replan: bool = False, **options):
        self.env = lagrange_env(env)
        self.system = self.env.system
        refuse_time_dependent(self.env, "The plan tracker")
        # it predicts each row's next state to tell a new episode from a tracked one
        self.env.plant.require_observed("The plan tracker")
        self.lqr = LQRPolicy(env)
        self.replan = bool(replan)
        self.options = options
        self.S = action_matrix(self.env)
        self._nominal: dict[bytes, Tracker] = {}
        self._trackers: list[Tracker | None] = []
        self._k = np.zeros(0, dtype=np.int64)
        self._expected: np.ndarray | None = None
        self.plans_made = 0
        self.plans_missed = 0

    # ---- plans ---------------------------------------------------------------------------
    def nominal(self, x0: np.ndarray, u0: np.ndarray, start=None) -> Tracker:
        """The nominal plan to operating point x0 (from the start distribution's centre, or
        from `start` when the task's start is a function), with its gains; cached."""
        key = x0.tobytes()
        tracker = self._nominal.get(key)
        if tracker is None:
            centre = start_centre(self.env)
            origin = centre if centre is not None else start
            p = plan(self.env, start=origin, goal=x0, strict=False, **self.options)
            tracker = tvlqr(self.env, p, u0, self.lqr)
            self._nominal[key] = tracker
        return tracker

    def tracker_for(self, x: np.ndarray, x0: np.ndarray, u0: np.ndarray) -> Tracker:
        """The tracker of an episode starting at x towards the operating point (x0, u0)."""
        nominal = self.nominal(x0, u0, x)
        if not self.replan:
            return nominal
        try:
            p = plan(self.env, start=x, goal=x0, guess=nominal.plan, **self.options)
        except PlanError:
            self.plans_missed += 1
            return nominal
        self.plans_made += 1
        return tvlqr(self.env, p, u0, self.lqr)

    # ---- acting --------------------------------------------------------------------------
    def _new_episodes(self, x: np.ndarray, episode_start) -> np.ndarray:
        n = len(x)
        if self._expected is None or len(self._expected) != n:
            self._trackers = [None] * n
            self._k = np.zeros(n, dtype=np.int64)
            return np.ones(n, dtype=bool)
        err = self.lqr.error(x, self._expected)
        new = np.abs(err).max(axis=1) > self.RESET_TOLERANCE
        if episode_start is not None:
            new |= np.broadcast_to(np.asarray(episode_start, dtype=bool).ravel(), (n,))
        return new

    def act(self, x: np.ndarray, x0: np.ndarray, u0: np.ndarray, episode_start=None):
        """Normalised actions (N, n_a) for physical states x (N, 2n) of consecutive steps."""
        new = self._new_episodes(x, episode_start)
        for i in np.flatnonzero(new):
            self._trackers[i] = self.tracker_for(x[i], x0[i], u0[i])
            self._k[i] = 0
        a = self.lqr.act(x, x0, u0)  # the hand-over, replaced where a plan is running
        for i, tracker in enumerate(self._trackers):
            k = self._k[i]
            if tracker is None or k >= tracker.plan.steps:
                continue
            p = tracker.plan
            dx = self.lqr.error(x[i], p.x[k])
            a[i] = np.clip(p.actions[k] - tracker.K[k] @ dx, -1.0, 1.0)
        self._k += 1
        u = a @ self.S.T
        self._expected = env_step(self.env, x, u)
        return a

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        """stable-baselines3's interface: (action, None) for one or a batch of observations
        (consecutive calls follow the same rows through their episodes)."""
        obs = np.asarray(observation, dtype=np.float64)
        flat = obs.reshape(-1, obs.shape[-1])
        x = self.env.state_from_observation(flat)
        x0, u0 = self.env.operating_point(flat)
        a = self.act(x, x0, u0, episode_start).astype(np.float32)
        return a.reshape(obs.shape[:-1] + a.shape[-1:]), None
