"""Closed-loop evaluation of a controller from a region around the task's operating point,
and the search for the largest such region it holds."""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium as gym
import numpy as np

from ..common import lagrange_env, spec
from ..control.linear import _indices, state_names
from ..control.lqr_policy import LQRPolicy, start_region
from .episodes import run_episodes


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


def expected_region(env) -> dict[str, float]:
    """The start region the env's task expects LQR to hold (see `agents.lqr.start_region`)."""
    env = lagrange_env(env)
    hints = env.task.lqr
    return start_region(hints, hints.states or state_names(env.system))


def perturbed_starts(env, region: dict[str, float], rng: np.random.Generator) -> np.ndarray:
    """Operating points of the env's current goals (rows) plus uniform perturbations of
    half-width region[name] in each named state component (physical units)."""
    names = state_names(env.system)
    x0, _ = env.operating_point()
    x = np.atleast_2d(np.array(x0, dtype=np.float64))
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
    the task's expected region, `expected_region`). `policy`: an object with SB3's
    `predict` built for the vector env, a callable vec -> such an object, or None for
    `LQRPolicy`. An episode succeeds if `info["is_success"]` holds at its last step."""
    vec = gym.make_vec(
        spec(env_id), num_envs=episodes, vectorization_mode="vector_entry_point", **env_kwargs
    )
    try:
        region = dict(expected_region(vec) if region is None else region)
        region = {k: scale * v for k, v in region.items()}
        vec.reset(seed=seed)  # draws each copy's goal
        goals = vec.unwrapped.goal
        starts = perturbed_starts(vec.unwrapped, region, np.random.default_rng(seed))
        obs, _ = vec.reset(seed=seed, options={"state": starts, "goal": goals})
        if policy is None:
            policy = LQRPolicy(vec)
        elif isinstance(policy, type) or not hasattr(policy, "predict"):
            policy = policy(vec)
        stats = run_episodes(vec, policy, obs)
        return ClosedLoop(stats.returns, stats.successes, region)
    finally:
        vec.close()


def largest_region(
    env_id: str, policy=None, target: float = 0.99, episodes: int = 100, seed: int = 0
) -> tuple[float, ClosedLoop]:
    """The largest multiple of the task's expected region (to 1/16 of a doubling) from
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
