"""Training throughput: the env-steps a budget run trains per second, this tree against another.

    OMP_NUM_THREADS=1 python -m benchmarks.training_speed [--baseline PATH] [--seconds 60]
        [--rounds 1] [--out DIR] [SYSTEM ...]

A time budget is what `agents.check` and the learning benchmark give every agent, so the
steps a run makes in it are what the learner gets to learn from: the env, the training
env's wrappers (the episode monitor, the reward scale, the LQR potential, the success
bonus, VecNormalize), PPO's updates, the evaluations and the saves all share it. Each
measurement is one `python -m agents.train SYSTEM --budget S --seed 0` in a new process
(`OMP_NUM_THREADS=1`, one core), in a run directory of its own; its rate is the steps of
its last evaluation (the end of training) over that evaluation's wall-clock seconds from
the start of training (`eval.csv`).

`--baseline PATH` measures another checkout of this project (for example the commit before
a change, in a second `git worktree`) in the same run: within each round the two trees
train the same system side by side, one process each (the first started alternates), so a
shared machine's load falls on both, and the table gives the medians and the ratio of this
tree to the baseline. Runs that are solved stop early; their rate is still the steps over
the seconds they trained. The systems are given as `agents.train` takes them (`MODULE:ID`
for the examples); by default the three-link arm example (64 copies, a goal drawn at reset:
the LQR potential designs one regulator per goal), the Segway example (an operating point
that reads the state), the acrobot (its hand-over to LQR) and the bead on a rotating rod.
"""

from __future__ import annotations

import argparse
import csv
import os
import statistics
import subprocess
import sys
import tempfile
from contextlib import ExitStack
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SYSTEMS = (
    "examples.three_link_arm:Examples/ThreeLinkArm-v0",
    "examples.segway:Examples/Segway-v0",
    "Lagrange/Acrobot-v2",
    "Lagrange/BeadOnRod-v1",
)


def start(tree: Path, system: str, seconds: float, run_dir: Path, log) -> subprocess.Popen:
    """`agents.train SYSTEM --budget S --seed 0` of `tree` in a new process, one core."""
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(tree)}
    command = [sys.executable, "-m", "agents.train", system, "--budget", f"{seconds:g}s"]
    command += ["--seed", "0", "--run-dir", str(run_dir), "--no-progress"]
    return subprocess.Popen(command, cwd=tree, env=env, stdout=log, stderr=subprocess.STDOUT)


def rate(run_dir: Path) -> float:
    """Env-steps per second of training: the last evaluation's steps over its seconds."""
    with open(run_dir / "eval.csv", newline="", encoding="utf-8") as fh:
        last = list(csv.DictReader(fh))[-1]
    return int(last["timesteps"]) / float(last["wall_s"])


def measure(trees: dict[str, Path], system: str, seconds: float, k: int, out: Path) -> dict:
    """One round: every tree trains `system` at once; {tree name: steps/s}."""
    names = list(trees)
    names = names[k % len(names) :] + names[: k % len(names)]  # who starts first alternates
    runs = {}
    with ExitStack() as logs:
        for name in names:
            run_dir = out / f"{system.replace(':', '_').replace('/', '-')}_{name}_{k}"
            log = logs.enter_context(open(run_dir.with_suffix(".log"), "w", encoding="utf-8"))
            runs[name] = (run_dir, start(trees[name], system, seconds, run_dir, log))
        for name, (run_dir, process) in runs.items():
            if process.wait() != 0:
                raise SystemExit(f"{name}: agents.train {system} failed; see {run_dir}.log")
    return {name: rate(run_dir) for name, (run_dir, _) in runs.items()}


def table(results: dict[str, dict[str, list[float]]], baseline: bool) -> str:
    head = "| system | steps/s |" + (" baseline steps/s | ratio |" if baseline else "")
    lines = [head, "|---" * (4 if baseline else 2) + "|"]
    for system, rates in results.items():
        ours = statistics.median(rates["this"])
        row = f"| {system} | {ours:,.0f} |"
        if baseline:
            theirs = statistics.median(rates["baseline"])
            row += f" {theirs:,.0f} | {ours / theirs:.2f} |"
        lines.append(row)
    return "\n".join(lines)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("systems", nargs="*", default=list(SYSTEMS))
    parser.add_argument("--baseline", type=Path, help="another checkout of this project")
    parser.add_argument("--seconds", type=float, default=60.0, help="each run's budget")
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--out", type=Path, help="keep the runs here (default: a temporary)")
    args = parser.parse_args(argv)
    trees = {"this": ROOT}
    if args.baseline is not None:
        if not (args.baseline / "agents" / "train.py").is_file():
            parser.error(f"--baseline {args.baseline} is not a checkout of this project")
        trees["baseline"] = args.baseline.resolve()
    with tempfile.TemporaryDirectory() as scratch:
        out = args.out or Path(scratch)
        out.mkdir(parents=True, exist_ok=True)
        results: dict[str, dict[str, list[float]]] = {}
        for system in args.systems:
            rates: dict[str, list[float]] = {name: [] for name in trees}
            for k in range(args.rounds):
                for name, value in measure(trees, system, args.seconds, k, out).items():
                    rates[name].append(value)
            results[system] = rates
            medians = ", ".join(f"{n} {statistics.median(v):,.0f}" for n, v in rates.items())
            print(f"{system}: {medians} env-steps/s", flush=True)
    print()
    print(table(results, args.baseline is not None))


if __name__ == "__main__":
    main()
