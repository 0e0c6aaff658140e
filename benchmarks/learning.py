"""The learning benchmark: systems x learners, each trained with the task's derived
defaults until solved within a wall-clock budget (agents.learning.budget).

    python benchmarks/learning.py                                    # every system, 4 learners
    python benchmarks/learning.py examples.furuta:Examples/Furuta-v0 --algos ppo,sac --budget 5m
    python benchmarks/learning.py --seeds 0,1,2 --budget 10m --out runs/learning
    python benchmarks/learning.py --from runs/a/results.csv runs/b/results.csv --out runs/all

Systems (positional, default): every registered Lagrange env and every env that a module
of `examples/` registers when imported (a module that does not import, for want of an
optional package, is named and skipped), so a new example joins by being there. Each run
trains with `agents.train.train(..., budget=...)`: evaluations of 20 episodes every
`agents.learning.budget.budget_eval_freq` steps, stop at >= 80 % at three in a row
confirmed on fresh starts (`agents.learning.budget.RULE`), the confirmed model kept (else
the best). The kept
model is then scored on 20 seeded episodes (seeds 0..19, as `agents.check`): success with
Wilson's 95 % interval. The columns "to 80 %" give the training seconds and env-steps at
which the rule was met (blank: not within the budget). A run that hands over to LQR is
also scored alone: where a start lies inside LQR's set the agent alone is counted, else
the hand-over, and the row gives the other score and the share of steps LQR acted.

Writes OUT/results.md (the table) and OUT/results.csv, atomically, after every run (an
interrupted benchmark keeps what it measured). Run it with `nice` on a shared machine: each
run holds one core for up to the budget.
"""

from __future__ import annotations

import argparse
import csv
import datetime
import importlib
import io
import os
import pkgutil
import platform
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import gymnasium as gym  # noqa: E402

from agents.common import (  # noqa: E402
    UserError,
    check_env_id,
    check_env_ids,
    env_slug,
    fail,
    register_envs,
    seed_int,
    writable_folder,
    write_atomic,
)
from agents.learning.budget import budget_arg  # noqa: E402
from agents.scoring.report import wilson_interval  # noqa: E402

ALGOS = ("ppo", "sac", "tqc", "crossq")
DEFAULT_BUDGET = 600.0
FIELDS = ("system algo seed success n low high to80_s to80_steps trained_steps train_s "
          "lqr_share note budget_s").split()  # fmt: skip


def example_systems() -> tuple[list[str], list[str]]:
    """(env ids, skipped notes): every env the modules of `examples/` register."""
    import examples

    ids, skipped = [], []
    for info in pkgutil.iter_modules(examples.__path__):
        name = f"examples.{info.name}"
        try:
            module = importlib.import_module(name)
        except Exception as exc:  # an optional dependency missing: say so, go on
            skipped.append(f"{name}: {type(exc).__name__}: {str(exc)[:80]}")
            continue
        # the ids whose task is one of the module's own (imported earlier or now)
        tasks = {id(v) for v in vars(module).values()}
        ids += [f"{name}:{e}" for e, spec in sorted(gym.registry.items())
                if id(spec.kwargs.get("task")) in tasks]  # fmt: skip
    return ids, skipped


def default_systems() -> tuple[list[str], list[str]]:
    ids, skipped = example_systems()
    return list(register_envs()) + ids, skipped


def run_one(system: str, algo: str, seed: int, seconds: float, out: Path) -> dict:
    """Train one learner on one system within the budget and score the kept model."""
    from agents import evaluate as programs
    from agents.scoring.learned import alone_rows, chance_note
    from agents.train import train

    env_id = check_env_id(system, lagrange=True)
    run_dir = out / "runs" / env_slug(env_id) / f"{algo}_seed{seed}"
    result = train(env_id, algo, seed=seed, run_dir=run_dir, overwrite=True, progress=False,
                   eval_episodes=20, budget=seconds)  # fmt: skip
    stats = programs.evaluate(env_id, str(result.model_path), 20, 0)
    quiet = lambda _: None  # noqa: E731
    alone, note, share, inside = alone_rows(programs, env_id, algo, result.model_path, 20, 0,
                                            quiet)  # fmt: skip
    if alone and inside:  # a start inside LQR's set: the agent's own success counts
        note = f"with hand-over {stats.success_rate:.0%}; {note}"
        stats = alone[0].stats
    elif alone:  # every start outside it: the hand-over's, beside the agent alone
        note = f"agent alone {alone[0].stats.success_rate:.0%}; {note}"
    k, n = int(stats.successes.sum()), len(stats.successes)
    note = "; ".join(filter(None, (note, chance_note(run_dir, k, n))))
    interval = wilson_interval(k, n)
    solved = result.solved or {}
    return {
        "system": env_id, "algo": algo, "seed": seed, "success": k / n, "n": n,
        "low": interval.low, "high": interval.high,
        "to80_s": solved.get("seconds", ""), "to80_steps": solved.get("timesteps", ""),
        "trained_steps": result.timesteps, "train_s": round(result.wall_s, 1),
        "lqr_share": "" if share is None else round(share, 3), "note": note,
        "budget_s": seconds,
    }  # fmt: skip


def table(rows: list[dict], seconds: float, header: str) -> str:
    lines = [
        header,
        "",
        "| system | learner | seed | success (20 episodes, 95 % Wilson) | to 80 %: s | to 80 %: "
        "env-steps | trained steps | training s | note |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        budget = r.get("budget_s") or seconds  # each run's own budget, where it says it
        to_s = (
            f"{r['to80_s']:.0f}"
            if r["to80_s"] != ""
            else (f"not in {budget:g} s" if budget else "not in its budget")
        )
        to_n = f"{r['to80_steps']:,}" if r["to80_steps"] != "" else ""
        lines.append(
            f"| {r['system']} | {r['algo']} | {r['seed']} | {r['success']:.0%} "
            f"[{r['low']:.0%}, {r['high']:.0%}] | {to_s} | {to_n} | {r['trained_steps']:,} "
            f"| {r['train_s']:.0f} | {r['note']} |"
        )
    return "\n".join(lines + seeds_table(rows)) + "\n"


def seeds_table(rows: list[dict]) -> list[str]:
    """Lines of a table over training seeds, for each system and learner run with more than
    one: how many seeds reached 80 %, the success over all their scored episodes with
    Wilson's 95 % interval (each seed's agent scored on the same starts), and the median
    seconds to 80 % of those that reached it. Empty where every pair ran one seed."""
    groups: dict[tuple[str, str], list[dict]] = {}
    for r in rows:
        groups.setdefault((r["system"], r["algo"]), []).append(r)
    if all(len(g) < 2 for g in groups.values()):
        return []
    lines = ["", "Across training seeds:", "",
             "| system | learner | seeds | at >= 80 % | success (all episodes, 95 % Wilson) "
             "| to 80 %: median s |", "|---|---|---|---|---|---|"]  # fmt: skip
    for (system, algo), g in groups.items():
        k = sum(round(float(r["success"]) * int(r["n"])) for r in g)
        n = sum(int(r["n"]) for r in g)
        interval = wilson_interval(k, n)
        times = [float(r["to80_s"]) for r in g if r["to80_s"] != ""]
        median = f"{statistics.median(times):.0f}" if times else ""
        met = sum(float(r["success"]) >= 0.8 for r in g)
        lines.append(
            f"| {system} | {algo} | {', '.join(str(r['seed']) for r in g)} | {met} of {len(g)} "
            f"| {k / n:.0%} [{interval.low:.0%}, {interval.high:.0%}] | {median} |"
        )
    return lines


def read_rows(paths: list[str]) -> list[dict]:
    """The rows of earlier runs' results.csv files (`--from`), typed as `run_one` gives them;
    UserError of one line for a file given twice, missing, without runs or a column, with a
    value that is no number, or a run that another file holds too."""
    rows, seen, where = [], set(), {}
    for path in paths:
        if Path(path).resolve() in seen:
            raise UserError(f"--from: {path} is given twice (its runs would count twice).")
        seen.add(Path(path).resolve())
        for line, r in _csv_rows(path):
            key = (r["system"], r["algo"], r["seed"])
            if key in where:
                raise UserError(
                    f"--from: the run {' '.join(map(str, key))} is in {where[key]} and in "
                    f"{path}:{line}; give each run once."
                )
            where[key] = f"{path}:{line}"
            rows.append(r)
    return rows


def _csv_rows(path: str):
    """(line number, typed row) of one results.csv."""
    if not Path(path).is_file():
        raise UserError(f"--from: {path} is not a file.")
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        needed = [k for k in FIELDS if k != "budget_s"]  # (older files have no budget)
        missing = [k for k in needed if k not in (reader.fieldnames or [])]
        if missing:
            raise UserError(
                f"--from: {path} lacks the column(s) {', '.join(missing)}; a results.csv of "
                f"this benchmark has {', '.join(FIELDS)}."
            )
        count = 0
        for count, r in enumerate(reader, start=1):
            yield count + 1, _typed(r, f"{path}:{count + 1}")
    if count == 0:
        raise UserError(f"--from: {path} holds no runs (a header alone).")


def _typed(r: dict, where: str) -> dict:
    kinds = {"success": float, "low": float, "high": float, "train_s": float, "seed": int,
             "n": int, "trained_steps": int, "to80_s": float, "to80_steps": int,
             "budget_s": float}  # fmt: skip
    for key, kind in kinds.items():
        blank = key in ("to80_s", "to80_steps", "budget_s")  # blank: not met / not recorded
        value = r.get(key) or ""
        if blank and value == "":  # (a run that did not record its budget says none)
            r[key] = ""
            if key == "budget_s":
                r.pop(key, None)
            continue
        try:
            r[key] = kind(value)
        except ValueError:
            what = "an integer" if kind is int else "a number"
            raise UserError(
                f"--from: {where}: column {key!r} must be {what}, got {value!r:.40}."
            ) from None
    return r


def write(rows: list[dict], out: Path, seconds: float, header: str) -> None:
    write_atomic(out / "results.md", table(rows, seconds, header))
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, FIELDS)
    writer.writeheader()
    writer.writerows(rows)
    write_atomic(out / "results.csv", buffer.getvalue())


def checked(args) -> tuple[list[str], list[str], list[int], list[str]]:
    """(systems, algos, seeds, skipped notes) of the command line, each checked before any
    work; UserError of one line naming the option, the value and what it may be."""
    from agents.learning.hparams import check_algo_name

    algos = _listed("--algos", args.algos, check_algo_name)
    seeds = _listed("--seeds", args.seeds, _seed)
    check_env_ids(args.systems, lagrange=True)
    writable_folder(args.out, "--out")
    systems, skipped = (args.systems, []) if args.systems else default_systems()
    return systems, algos, seeds, skipped


def _seed(text: str) -> int:
    try:
        return seed_int(text)
    except argparse.ArgumentTypeError as exc:
        raise UserError(str(exc)) from None


def _listed(option: str, text: str, check) -> list:
    """The comma-separated entries of `option`, each checked, once each."""
    names = [a.strip() for a in text.split(",") if a.strip()]
    if not names:
        raise UserError(f"{option} names nothing ({text!r}); give one or more, comma-separated.")
    repeated = sorted({a for a in names if names.count(a) > 1})
    if repeated:
        raise UserError(f"{option} names {', '.join(repeated)} twice; give each once.")
    try:
        return [check(a) for a in names]
    except ValueError as exc:
        raise UserError(f"{option}: {exc}") from None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("systems", nargs="*", help="env ids or module:NS/Env-v0 (default: all)")
    parser.add_argument("--algos", default=",".join(ALGOS), help="comma-separated learners")
    parser.add_argument("--budget", type=budget_arg, help="per run (default 10m)")
    parser.add_argument("--seeds", default="0", help="training seeds, comma-separated")
    parser.add_argument("--out", default="runs/learning", help="output directory")
    parser.add_argument("--from", dest="sources", nargs="+", metavar="CSV",
                        help="no training: one table from earlier runs' results.csv files "
                        "(runs split over several processes), written to OUT")  # fmt: skip
    args = parser.parse_args(argv)
    if args.sources:
        try:
            rows = read_rows(args.sources)
            writable_folder(args.out, "--out")
        except UserError as exc:
            fail(parser, exc)
        header = f"# Learning benchmark\n\nThe runs of {', '.join(args.sources)}."
        write(rows, Path(args.out), args.budget, header)
        print(table(rows, args.budget, header))
        return 0
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    from agents.common import set_torch_threads

    args.budget = args.budget or DEFAULT_BUDGET
    try:
        systems, algos, seeds, skipped = checked(args)
    except UserError as exc:
        fail(parser, exc)
    set_torch_threads(1)
    out = Path(args.out)
    header = (
        f"# Learning benchmark\n\n{datetime.date.today()}, {platform.node() or 'this machine'}"
        f" ({os.cpu_count()} cores), budget {args.budget:g} s per run, derived defaults "
        f"(agents.learning.defaults). Command: `python benchmarks/learning.py "
        f"{' '.join(sys.argv[1:] if argv is None else argv)}`"
        + "".join(f"\n\nSkipped: {s}" for s in skipped)
    )
    rows: list[dict] = []
    for system in systems:
        for algo in algos:
            for seed in seeds:
                print(f"{system} {algo} seed {seed} ...", file=sys.stderr, flush=True)
                try:
                    rows.append(run_one(system, algo, seed, args.budget, out))
                except Exception as exc:  # one failing system must not lose the others
                    print(f"  failed: {type(exc).__name__}: {exc}", file=sys.stderr)
                    continue
                r = rows[-1]
                print(f"  {r['success']:.0%}, to 80 %: {r['to80_s'] or '-'} s", file=sys.stderr)
                write(rows, out, args.budget, header)
    print(table(rows, args.budget, header))
    return 0


if __name__ == "__main__":
    sys.exit(main())
