"""The main job: check every environment with the baselines, LQR and a short SB3 training.

    python -m agents.check

For each environment (default: the built-in Lagrange envs; any Lagrange env id or
Gymnasium's module:Env-v0 form): random, zero torque, the task's heuristic (where it
declares one), LQR, and an SB3 agent trained with the task's algorithm and hyperparameters
(`agents.hparams`), each scored on the same seeded episodes. Prints a Markdown
comparison table and writes it, a CSV and plots to runs/check/ (training runs under
runs/check/train/; a re-run resumes them from their checkpoints, --fresh starts over).
"""

from __future__ import annotations

import argparse
import csv
import io
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import hparams
from .common import (
    DEFAULT_TORCH_THREADS,
    atomic_path,
    check_env_id,
    env_slug,
    fail,
    non_negative_int,
    positive_int,
    register_envs,
    set_torch_threads,
    write_text_atomic,
)
from .evaluate import BASELINES, EvalStats, evaluate, heuristic_of
from .train import ALGORITHMS, train


@dataclass(frozen=True)
class Row:
    env_id: str
    agent: str
    stats: EvalStats
    wall_s: float  # evaluation (and, for the trained agent, training) time, s
    note: str = ""


def check_env(
    env_id: str,
    algo: str | None,
    episodes: int,
    seed: int,
    out: Path,
    timesteps: int | None,
    fresh: bool,
    progress: bool,
    log=print,
    hyperparams: str | Path | None = None,
) -> list[Row]:
    """Every baseline, LQR and the trained agent on one environment."""
    algo = algo or hparams.check_algo(env_id)
    heuristic = heuristic_of(env_id)
    rows = []
    for name in BASELINES:
        if name == "heuristic" and heuristic is None:
            continue
        start = time.perf_counter()
        stats = evaluate(env_id, name, episodes, seed)
        note = heuristic.description if name == "heuristic" else ""
        rows.append(Row(env_id, name, stats, time.perf_counter() - start, note))
        log(f"  {name:>9}: {stats.summary()}")
    start = time.perf_counter()
    hp = hparams.load(algo, env_id, hyperparams)
    budget = timesteps if timesteps is not None else hp["n_timesteps"]
    log(f"  training {algo} for {budget} steps ...")
    result = train(
        env_id,
        algo,
        timesteps=budget,
        seed=seed,
        run_dir=out / "train" / env_slug(env_id) / f"{algo}_seed{seed}",
        resume=not fresh,
        overwrite=fresh,
        progress=progress,
        hyperparams=hyperparams,
    )
    stats = evaluate(env_id, str(result.model_path), episodes, seed)
    note = f"{result.timesteps} steps"
    rows.append(Row(env_id, algo, stats, time.perf_counter() - start, note))
    log(f"  {algo:>9}: {stats.summary()} ({note}, {rows[-1].wall_s:.0f} s)")
    return rows


def markdown_table(rows: list[Row]) -> str:
    lines = [
        "| environment | agent | return (mean +- std) | success | length | time (s) | note |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        s = r.stats
        lines.append(
            f"| {r.env_id} | {r.agent} | {s.mean_return:.1f} +- {s.std_return:.1f} | "
            f"{s.success_rate:.0%} | {s.mean_length:.0f} | {r.wall_s:.1f} | {r.note} |"
        )
    return "\n".join(lines)


def findings(rows: list[Row]) -> list[str]:
    """One sentence per environment: the best agent, and LQR against the trained agent."""
    out = []
    for env_id in dict.fromkeys(r.env_id for r in rows):
        mine = {r.agent: r.stats for r in rows if r.env_id == env_id}
        algo = [r.agent for r in rows if r.env_id == env_id][-1]  # the trained agent is last
        best = max(mine, key=lambda a: (mine[a].success_rate, mine[a].mean_return))
        text = f"{env_id}: best {best}"
        if "lqr" in mine and algo in mine:
            lqr, rl = mine["lqr"], mine[algo]
            lqr_wins = (lqr.success_rate, lqr.mean_return) > (rl.success_rate, rl.mean_return)
            winner = "LQR beats" if lqr_wins else "LQR does not beat"
            text += (
                f"; {winner} {algo.upper()} (success {lqr.success_rate:.0%} vs "
                f"{rl.success_rate:.0%}, return {lqr.mean_return:.1f} vs {rl.mean_return:.1f})"
            )
        baselines = [mine[a] for a in ("zero", "random") if a in mine]
        if algo in mine and baselines:
            beats = all(mine[algo].mean_return > b.mean_return for b in baselines)
            text += f"; {algo.upper()} {'beats' if beats else 'does NOT beat'} zero and random"
        out.append(text + ".")
    return out


def write_csv(rows: list[Row], path: Path) -> None:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(
        [
            "env_id",
            "agent",
            "mean_return",
            "std_return",
            "success_rate",
            "mean_length",
            "wall_s",
            "note",
        ]
    )
    for r in rows:
        s = r.stats
        writer.writerow(
            [
                r.env_id,
                r.agent,
                f"{s.mean_return:.4f}",
                f"{s.std_return:.4f}",
                f"{s.success_rate:.4f}",
                f"{s.mean_length:.1f}",
                f"{r.wall_s:.2f}",
                r.note,
            ]
        )
    write_text_atomic(path, buf.getvalue())


def plot_comparison(rows: list[Row], path: Path) -> None:
    """One panel per environment: mean return +- std of each agent, success rate printed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    env_ids = list(dict.fromkeys(r.env_id for r in rows))
    cols = min(3, len(env_ids))
    nrows = -(-len(env_ids) // cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(4.6 * cols, 3.4 * nrows), squeeze=False)
    for ax in axes.flat[len(env_ids) :]:
        ax.set_visible(False)
    for ax, env_id in zip(axes.flat, env_ids):
        mine = [r for r in rows if r.env_id == env_id]
        y = np.arange(len(mine))
        means = [r.stats.mean_return for r in mine]
        ax.barh(y, means, xerr=[r.stats.std_return for r in mine], color="tab:blue", alpha=0.7)
        ax.set_yticks(y, [f"{r.agent}\n{r.stats.success_rate:.0%}" for r in mine])
        ax.invert_yaxis()
        ax.set(title=env_id.split("/")[-1], xlabel="episode return")
        ax.grid(axis="x", alpha=0.3)
    fig.suptitle("agents on every environment (label: success rate)")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)


def run_check(
    env_ids: list[str] | None = None,
    algo: str | None = None,
    episodes: int = 20,
    seed: int = 0,
    out: str | Path = "runs/check",
    timesteps: int | None = None,
    fresh: bool = False,
    progress: bool = True,
    hyperparams: str | Path | None = None,
) -> list[Row]:
    """Check every environment (default: all of `envs.ENV_IDS`); write the report to `out`.
    algo: the algorithm to train everywhere (default: per env, the task's `algo`)."""
    env_ids = list(env_ids) if env_ids else list(register_envs())
    if not env_ids:
        raise ValueError("No environments to check: the `envs` package registers none.")
    env_ids = [check_env_id(e, lagrange=True) for e in env_ids]
    out = Path(out)
    set_torch_threads(DEFAULT_TORCH_THREADS)
    start = time.perf_counter()
    rows: list[Row] = []
    for i, env_id in enumerate(env_ids, 1):
        print(f"[{i}/{len(env_ids)}] {env_id}", file=sys.stderr, flush=True)
        log = lambda text: print(text, file=sys.stderr, flush=True)  # noqa: E731
        rows += check_env(
            env_id, algo, episodes, seed, out, timesteps, fresh, progress, log, hyperparams
        )
    total = time.perf_counter() - start
    table = markdown_table(rows)
    notes = "\n".join(f"- {line}" for line in findings(rows))
    trained = "; ".join(
        f"{r.env_id}: {r.agent.upper()} for {r.note}" for r in rows if r.agent not in BASELINES
    )
    report = (
        f"# Agents on every environment\n\n{episodes} episodes per agent (seeds {seed}.."
        f"{seed + episodes - 1}), success = the task's criterion at the last step. "
        f"Trained: {trained}. Total wall time {total:.0f} s.\n\n{table}\n\n"
        f"## Findings\n\n{notes}\n\n"
        f"![comparison](comparison.png)\n"
    )
    write_text_atomic(out / "results.md", report)
    write_csv(rows, out / "results.csv")
    plot_comparison(rows, out / "comparison.png")
    print(table)
    print()
    print(notes)
    print(f"\nTotal wall time {total:.0f} s. Report, CSV and plots in {out}/")
    return rows


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m agents.check",
        description="Check every environment with random, zero-torque and heuristic "
        "baselines, LQR and a short stable-baselines3 training; print a Markdown "
        "comparison and write it with plots to --out.",
    )
    parser.add_argument(
        "env_ids",
        nargs="*",
        help="Lagrange env ids or module:NS/Env-v0 (default: the built-in Lagrange envs)",
    )
    parser.add_argument(
        "--algo",
        help=f"train this ({', '.join(ALGORITHMS)}) on every env "
        "(default: per env, the algorithm its task declares)",
    )
    parser.add_argument(
        "--hyperparams",
        metavar="FILE",
        help="YAML overriding the packaged hyperparameters (format of agents/hyperparams/*.yml)",
    )
    parser.add_argument("--episodes", type=positive_int, default=20)
    parser.add_argument("--seed", type=non_negative_int, default=0)
    parser.add_argument(
        "--timesteps",
        type=positive_int,
        help="training budget per env (default: the YAML's n_timesteps)",
    )
    parser.add_argument("--out", default="runs/check", help="output directory")
    parser.add_argument("--fresh", action="store_true", help="retrain instead of resuming")
    parser.add_argument("--no-progress", action="store_true", help="hide progress bars")
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.algo is not None and args.algo not in ALGORITHMS:
        parser.error(f"unknown algorithm {args.algo!r}; choose from {', '.join(ALGORITHMS)}")
    try:
        env_ids = [check_env_id(e, lagrange=True) for e in args.env_ids]
        if args.hyperparams is not None:
            for env_id in env_ids or register_envs():
                hparams.load(args.algo or hparams.check_algo(env_id), env_id, args.hyperparams)
    except ValueError as exc:
        fail(parser, exc)
    run_check(
        env_ids,
        args.algo,
        args.episodes,
        args.seed,
        args.out,
        args.timesteps,
        args.fresh,
        not args.no_progress,
        args.hyperparams,
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
