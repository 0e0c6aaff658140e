"""Benchmark of model-based control: trajectory optimisation + TVLQR against the baselines.

    python benchmarks/control.py                # 100 seeded episodes per row (seeds 0..99)
    python benchmarks/control.py --episodes 20  # quicker

Rows: the default acrobot (Lagrange/Acrobot-v2, elbow limit 2 m2 g l2) with plan + TVLQR
(target: >= 95 % success from its starting distribution); Lagrange/Acrobot-v1 (3 N*m) with
plan + TVLQR, the swing-up heuristic and LQR; and the Furuta pendulum of examples/ swung up
from hanging (its task with the start turned upside down and without the failure that
ends an episode beyond 0.6 rad, registered here as Examples/FurutaSwingUp-v0) with plan +
TVLQR. Each row runs its episodes side by side in the native vector env
(`agents.evaluate.evaluate`); the wall time includes planning.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")


from agents.evaluate import evaluate

FURUTA_SWING_UP = "Examples/FurutaSwingUp-v0"  # registered by examples.furuta_swing_up


ROWS = (
    ("Lagrange/Acrobot-v2", "plan"),
    ("Lagrange/Acrobot-v1", "plan"),
    ("Lagrange/Acrobot-v1", "heuristic"),
    ("Lagrange/Acrobot-v1", "lqr"),
    (FURUTA_SWING_UP, "plan"),
)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    importlib.import_module("examples.furuta_swing_up")
    print(f"{args.episodes} episodes per row, seeds {args.seed}..{args.seed + args.episodes - 1}")
    print("| env | agent | success | return (mean +- std) | wall s |")
    print("|---|---|---|---|---|")
    for env_id, agent in ROWS:
        start = time.perf_counter()
        stats = evaluate(env_id, agent, episodes=args.episodes, seed=args.seed)
        wall = time.perf_counter() - start
        print(
            f"| {env_id} | {agent} | {stats.success_rate:.0%} | {stats.mean_return:.1f} +- "
            f"{stats.std_return:.1f} | {wall:.0f} |",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
