"""Cold start: a new user's model from a fresh model cache, `make` + `reset` + first `step`.

    OMP_NUM_THREADS=1 python -m benchmarks.cold_start [--baseline PATH] [--rounds 3]
        [--models cart_pole furuta] [--warm]

Each measurement is one new Python process with a fresh, empty model cache
(``LAGRANGE_GYM_CACHE``) and the model's module copied to a fresh folder under a name of its
own, as a user's new model would be: its derivation, its generated kernels and its task
functions are all compiled for the first time (numba caches a task function's machine code
beside its module, in that fresh folder). What numba compiles once per machine (this
project's own model-independent kernels, cached beside their modules) is compiled before
the first round by one unmeasured run per tree. The process reports the seconds of
`gymnasium.make` (including importing the model's module, which derives nothing), `reset`,
the first `step`, the CPU seconds of the three together (on a loaded machine the wall
clock waits for other processes; CPU time does not; a thread compiling in the background
counts), and the seconds (wall and CPU) until the env's fused step is bound (`fused`,
`fused_cpu`: a tree that compiles it in the background, `envs.step.Step`, steps
by separate calls until then, with the same results).

`--baseline PATH` measures another checkout of this project (for example the commit before
a change, in a second `git worktree`) in the same run: the two trees alternate within each
round, so a shared machine's load falls on both, and the table gives the medians and the
ratio of this tree to the baseline. The models are the user-style examples in `examples/`
(the same source file for both trees: this tree's).

Where the cart-pole's cold seconds went (CPU seconds of each numba compilation, its own
time without what it compiles inside, from numba's compile events, on a busy two-core
machine), two rounds ago, at the start of this round and after it:

| compiled | two rounds ago | before | after |
|---|---|---|---|
| `accelerations_batch` (the checks when the env is made) | 1.9 | 0 (run as Python) | 0 |
| the five task functions | 2.1 | 1.0 (once) | 1.0 |
| numpy's broadcasting error text in the fused step (`Q[:, k] = ...`) | 1.9 | 0 (row loops) | 0 |
| `vsin`, `vcos`, `solve`, finiteness scans (model-independent) | 1.5 | 0 (once per machine) | 0 |
| `energy_terms`, `energy_batch` (the energy in `info`) | | 0.2 | 0.2 |
| `erk_batch`, a level of calls that re-optimises the integrator | 0.6 | 0 (not called) | 0 |
| `erk_rows` (rows in vector lanes; a single env has one) | 1.9 (and the next) | 1.0 | 0 |
| `erk_row`, `derivative_lanes` | | 0.9 | 0.9 |
| the fused step itself (LLVM re-optimises all it links) | 2.8 | 2.3 | 2.2, in the background |
| make, reset and first step, in all (CPU s) | 13.0 | 6.0 | 3.0 |

The rest of `make` (about 0.5 s) is the derivation, code generation and the imports. What
the first step still waited for was the model's integrator (`erk_row` and the derivative it
linked, `derivative_lanes`). The next round's fused step calls every kernel through its
address and compiles in 0.7-1.3 s of CPU, in the background after 2,000 steps. Then the
integrator and the kernels over rows became one for every model (`dynamics/stepping.py`,
`dynamics/rows.py`: compiled once per machine, calling the model's kernels through their
addresses): the cart-pole's compilations for make + reset + first step, CPU, 2.16 -> 1.36 s
(`erk_row` 0.68 s and `energy_batch` 0.14 s gone; left: `derivative_lanes` 0.34 s,
`energy_terms` 0.38 s, the task's functions 0.44 s), and make + reset + first step 2.76 ->
1.94 s (the Furuta pendulum 2.99 -> 2.21 s; medians of 3 alternating rounds, 2026-11-26,
where Python writes no bytecode).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MODELS = {"cart_pole": "Examples/CartPole-v0", "furuta": "Examples/Furuta-v0"}
PHASES = ("make", "reset", "step", "total", "cpu", "fused", "fused_cpu")

CHILD = """
import json, os, sys, time
c0, t0 = time.process_time(), time.perf_counter()
import gymnasium as gym
import numpy as np
import envs  # noqa: F401
t_import = time.perf_counter() - t0
sys.path.insert(0, sys.argv[1])
c1, t1 = time.process_time(), time.perf_counter()
__import__(sys.argv[2])
env = gym.make(sys.argv[3])
t2 = time.perf_counter()
env.reset(seed=0)
t3 = time.perf_counter()
env.step(np.zeros(env.action_space.shape, env.action_space.dtype))
t4, c4 = time.perf_counter(), time.process_time()
try:  # the fused step, where it compiles in the background
    from envs.step import wait_for_background
except ImportError:
    try:  # a tree before envs.step
        from envs.compiled import wait_for_background
    except ImportError:  # a tree that compiles it before the first step returns
        wait_for_background = None
if wait_for_background is not None:
    wait_for_background()
t5, c5 = time.perf_counter(), time.process_time()
print(json.dumps({"import": t_import, "make": t2 - t1, "reset": t3 - t2, "step": t4 - t3,
                  "total": t4 - t1, "cpu": c4 - c1, "fused": t5 - t1, "fused_cpu": c5 - c1}))
"""
"""The measured process: run with the tree as its working directory (so that it imports
that tree's packages), the model's folder, its module name and its env id as arguments."""


def measure(tree: Path, model: str, work: Path | None = None) -> dict[str, float]:
    """Seconds of each phase (`PHASES`) for `model` (a key of `MODELS`) in the checkout at
    `tree`: its module copied into the folder `work`, with the model cache `work/cache`
    (a new temporary folder, removed after, when `work` is None: a cold start)."""
    fresh = work is None
    work = Path(tempfile.mkdtemp(prefix="cold-start-")) if fresh else work
    try:
        name = f"user_{model}_{work.name.rsplit('-', 1)[-1]}"
        if not (work / f"{name}.py").exists():
            shutil.copy(ROOT / "examples" / f"{model}.py", work / f"{name}.py")
        env = dict(os.environ, OMP_NUM_THREADS="1", LAGRANGE_GYM_CACHE=str(work / "cache"))
        env.pop("PYTHONPATH", None)
        done = subprocess.run(
            [sys.executable, "-c", CHILD, str(work), name, MODELS[model]],
            cwd=tree, env=env, capture_output=True, text=True,
        )  # fmt: skip
        if done.returncode:
            last = (done.stderr.strip().splitlines() or ["no output"])[-1]
            raise RuntimeError(f"The cold start of {model} in {tree} failed: {last}")
        return json.loads(done.stdout.strip().splitlines()[-1])
    finally:
        if fresh:
            shutil.rmtree(work, ignore_errors=True)


def measure_warm(tree: Path, model: str) -> dict[str, float]:
    """`measure` of the same model in the same folder a second time: its model cache and
    its task functions' numba cache filled by the first (what an unchanged model costs in
    a new process)."""
    work = Path(tempfile.mkdtemp(prefix="cold-start-"))
    try:
        measure(tree, model, work)
        return measure(tree, model, work)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def summary(runs: list[dict[str, float]]) -> dict[str, float]:
    """The median of each phase over `runs`."""
    return {k: statistics.median(r[k] for r in runs) for k in PHASES}


def table(results: dict[tuple[str, str], list[dict]], trees: list[str]) -> str:
    """Markdown: a row per (model, kind) with each tree's medians, and the ratio of the
    first tree to the second where there are two."""
    head = ["model", "cache"]
    for tree in trees:
        head += [f"{tree}: {k} (s)" for k in PHASES]
    if len(trees) == 2:
        head += ["total ratio", "cpu ratio"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for model, kind in dict.fromkeys((m, k) for m, k, _ in results):
        row = [model, kind]
        medians = [summary(results[model, kind, tree]) for tree in trees]
        for m in medians:
            row += [f"{m[k]:.2f}" for k in PHASES]
        if len(trees) == 2:
            row += [f"{medians[0][k] / medians[1][k]:.2f}" for k in ("total", "cpu")]
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


def _tree(path: str) -> Path:
    tree = Path(path).resolve()
    if not (tree / "envs" / "__init__.py").is_file():
        raise argparse.ArgumentTypeError(f"{path} is not a checkout of this project (no envs/).")
    return tree


def main(argv: list[str] | None = None) -> str:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", type=_tree, help="another checkout to measure beside")
    parser.add_argument("--rounds", type=int, default=3, help="measurements per tree (median)")
    parser.add_argument("--models", nargs="+", choices=sorted(MODELS), default=["cart_pole"])
    parser.add_argument("--warm", action="store_true", help="also measure a warm model cache")
    args = parser.parse_args(argv)
    if args.rounds < 1:
        parser.error(f"--rounds must be at least 1, got {args.rounds}.")
    trees = {"this": ROOT}
    if args.baseline is not None:
        trees["baseline"] = args.baseline
    for tree in trees.values():  # numba's once-per-machine kernels of each tree
        measure(tree, args.models[0])
    kinds = {"fresh": measure, "warm": measure_warm} if args.warm else {"fresh": measure}
    results: dict = {}
    for r in range(args.rounds):
        for model in args.models:
            for kind, run in kinds.items():
                for label, tree in trees.items():
                    m = run(tree, model)
                    results.setdefault((model, kind, label), []).append(m)
                    print(f"round {r + 1} {model} {kind} {label}: total {m['total']:.2f} s, "
                          f"cpu {m['cpu']:.2f} s", file=sys.stderr, flush=True)  # fmt: skip
    text = table(results, list(trees))
    print(text)
    return text


if __name__ == "__main__":
    main()
