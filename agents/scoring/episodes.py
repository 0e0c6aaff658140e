"""The evaluation loop, shared by every program that scores a policy: a batch of episodes
side by side in a native vector env, each counted once, and how each one ended."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..common import spec

ENDINGS = ("success", "failure", "diverged", "time limit")


@dataclass(frozen=True)
class EvalStats:
    """Per-episode returns, lengths, success (the task's criterion at the last step) and how
    each episode ended: `terminated` (the task's failure or divergence, before the time
    limit) and, of those, `diverged` (`info["diverged"]`); neither means the time limit
    truncated it. Missing ending arrays read as all truncated."""

    returns: np.ndarray
    lengths: np.ndarray
    successes: np.ndarray
    terminated: np.ndarray | None = None
    diverged: np.ndarray | None = None

    def endings(self) -> dict[str, int]:
        """Episodes per way of ending (`ENDINGS`), each episode counted once: success, else
        diverged, else failure (terminated by the task), else time limit (truncated)."""
        none = np.zeros(len(self.returns), dtype=bool)
        success = np.asarray(self.successes, dtype=bool)
        terminated = none if self.terminated is None else np.asarray(self.terminated, bool)
        diverged = none if self.diverged is None else np.asarray(self.diverged, bool)
        diverged = diverged & ~success
        failure = terminated & ~diverged & ~success
        time_limit = ~(success | diverged | failure)
        counts = (success, failure, diverged, time_limit)
        return {name: int(c.sum()) for name, c in zip(ENDINGS, counts)}

    @property
    def mean_return(self) -> float:
        return float(self.returns.mean())

    @property
    def std_return(self) -> float:
        return float(self.returns.std())

    @property
    def success_rate(self) -> float:
        return float(self.successes.mean())

    @property
    def mean_length(self) -> float:
        return float(self.lengths.mean())

    def summary(self) -> str:
        """One line; sd is the spread of the returns over the episodes (the standard
        deviation), not an interval of the mean (`agents.scoring.report` gives those, 95 %)."""
        return (
            f"return {self.mean_return:.1f} (sd {self.std_return:.1f}), success "
            f"{self.success_rate:.0%}, length {self.mean_length:.0f} "
            f"({len(self.returns)} episodes: "
            + ", ".join(f"{n} {name}" for name, n in self.endings().items() if n)
            + ")"
        )


def run_episodes(venv, policy, obs, deterministic: bool = True) -> EvalStats:
    """The episode of every copy of the native vector env `venv` that starts at `obs` (it
    was just reset), under `policy` (SB3's `predict`); each copy's later episodes (the vector
    env autoresets it on the next step) are not counted."""
    n = venv.num_envs
    returns, lengths = np.zeros(n), np.zeros(n, dtype=np.int64)
    successes, ended_early, diverged = (np.zeros(n, dtype=bool) for _ in range(3))
    running = np.ones(n, dtype=bool)
    while running.any():
        action, _ = policy.predict(obs, deterministic=deterministic)
        obs, reward, terminated, truncated, info = venv.step(action)
        returns[running] += reward[running]
        lengths[running] += 1
        done = running & (terminated | truncated)
        successes[done] = np.asarray(info["is_success"])[done]
        ended_early[done] = np.asarray(terminated)[done]
        diverged[done] = np.asarray(info.get("diverged", np.zeros(n, bool)))[done]
        running &= ~done
    return EvalStats(returns, lengths, successes, ended_early, diverged & ended_early)


def score(
    env_id: str, build, episodes: int, seed: int, deterministic: bool = True, **options
) -> EvalStats:
    """The evaluation every program reports: `episodes` copies of `env_id`'s native vector
    env (env `options` such as `randomize`), copy i reset with seed + i, the first episode
    of each under the policy `build(venv)` returns. agents.evaluate scores with it, and so
    does the confirmation of a training run that met its stop rule
    (agents.learning.confirm): one code path, so the two cannot differ in their setup."""
    import gymnasium as gym

    mode = "vector_entry_point"
    venv = gym.make_vec(spec(env_id), num_envs=episodes, vectorization_mode=mode, **options)
    try:
        policy = build(venv)
        obs, _ = venv.reset(seed=seed)
        return run_episodes(venv, policy, obs, deterministic)
    finally:
        venv.close()
