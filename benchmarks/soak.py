"""Soak: a million random and bang-bang env-steps per environment, counting what must not
happen (non-finite observations, rewards, energies or states; observations outside the
space) and what may (episodes that diverged), and the memory the process grew by.

    python benchmarks/soak.py                  # every built-in env, 10^6 steps per policy
    python benchmarks/soak.py --steps 100000   # shorter
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym
import numpy as np

import envs

COPIES = 256


def rss_mb() -> float:
    """Peak resident memory of this process, MB (Linux reports KB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def soak(env_id: str, policy: str, steps: int, seed: int = 0) -> dict:
    vec = gym.make_vec(env_id, COPIES, vectorization_mode="vector_entry_point")
    space = vec.single_observation_space
    rng = np.random.default_rng(seed)
    obs, _ = vec.reset(seed=seed)
    bad = {"non-finite": 0, "outside space": 0}
    episodes = diverged = 0
    before = rss_mb()
    start = time.perf_counter()
    for _ in range(steps // COPIES):
        if policy == "random":
            a = rng.uniform(-1, 1, vec.action_space.shape)
        else:  # bang-bang: the limits, switched at random
            a = rng.choice([-1.0, 1.0], vec.action_space.shape)
        obs, rew, term, trunc, info = vec.step(a)
        values = (obs, rew, info["energy"], info["state"])
        bad["non-finite"] += sum(int((~np.isfinite(v)).sum()) for v in values)
        bad["outside space"] += int((~((obs >= space.low) & (obs <= space.high))).sum())
        episodes += int((term | trunc).sum())
        diverged += int(info["diverged"].sum())
    vec.close()
    return {
        **bad,
        "episodes": episodes,
        "diverged": diverged,
        "steps/s": steps / (time.perf_counter() - start),
        "memory growth (MB)": rss_mb() - before,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1_000_000, help="env-steps per policy")
    parser.add_argument("ids", nargs="*", default=list(envs.ENV_IDS))
    args = parser.parse_args(argv)
    print(
        "| env | policy | env-steps | non-finite | outside space | episodes | diverged | "
        "steps/s | memory growth (MB) |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    failed = False
    for env_id in args.ids:
        for policy in ("random", "bang-bang"):
            r = soak(env_id, policy, args.steps)
            failed |= r["non-finite"] > 0 or r["outside space"] > 0
            print(
                f"| {env_id} | {policy} | {args.steps} | {r['non-finite']} | "
                f"{r['outside space']} | {r['episodes']} | {r['diverged']} | "
                f"{r['steps/s']:.0f} | {r['memory growth (MB)']:.1f} |",
                flush=True,
            )
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
