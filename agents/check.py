"""The main job: check every environment with the baselines, LQR and a short SB3 training.

    python -m agents.check

For each environment (default: the built-in Lagrange envs; any Lagrange env id or
Gymnasium's module:Env-v0 form): random, zero torque, the task's heuristic (where it
declares one), LQR, and an SB3 agent trained with the task's algorithm and hyperparameters
(`agents.learning.hparams`), each scored on the same seeded episodes. Prints a Markdown
comparison (how episodes ended, 95 % intervals, findings claimed only where the intervals
separate: `agents.scoring.report`) and writes it, a CSV and a figure to runs/check/.

Every agent trains until solved (`agents.learning.budget`'s rule, confirmed on fresh
starts), at most 10 minutes and, where declared, at most its n_timesteps (the task's
hyperparameters, the packaged YAML's entry or a --hyperparams file; the built-in tasks
declare theirs): `agents.learning.declared`. `--budget` sets every agent's time, without a
step cap; `--timesteps N` trains every agent N steps, to the end.

Training runs live under runs/check/train/ENV/, one directory per budget (ALGO_seedS_600s,
ALGO_seedS_Nsteps). A re-run reuses a time budget's run that was solved or trained its
declared steps (`rundir.finished_run`) and trains any other afresh (a clock cannot be
resumed); it resumes (or reuses) a step budget's run, and refuses one whose stored
hyperparameters differ from today's unless --fresh retrains it; another budget starts a
fresh run and keeps the earlier. Training time is stored in the run directory
(`TIME_FILE`, summed over resumed segments); evaluation time excludes one-off compilation
and loading (an untimed first episode per agent).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

from envs.checks import Unsupported

from . import evaluate as programs
from . import params
from .common import (
    DEFAULT_TORCH_THREADS,
    UserError,
    check_env_id,
    check_env_ids,
    env_slug,
    fail,
    plain_warnings,
    positive_int,
    register_envs,
    seed_int,
    set_torch_threads,
    task_of,
    writable_folder,
    write_atomic,
)
from .evaluate import BASELINES, heuristic_of
from .learning import budget as budgets
from .learning import declared, hparams, randomization, timing
from .learning.budget import RULE, budget_arg
from .learning.defaults import describe
from .learning.fingerprint import check_fingerprint, task_fingerprint
from .learning.hparams import ALGOS, load_hyperparams
from .learning.rundir import (
    check_earlier_run,
    finished_run,
    latest_checkpoint,
    run_dir_of,
)
from .learning.timing import TIME_FILE as TIME_FILE
from .learning.timing import record_segment
from .scoring import learned
from .scoring.report import (
    Refused,
    Row,
    Training,
    findings,
    markdown_table,
    plot_comparison,
    report_text,
    training_lines,
    write_csv,
)
from .train import TrainingInterrupted, train


def train_timed(
    env_id,
    algo,
    budget,
    seed,
    run_dir,
    fresh,
    progress,
    hyperparams,
    randomize=None,
    seconds=None,
    cap=None,
):
    """train(), resuming a run of this budget found on disk unless `fresh`; returns the
    model's path and the run's `Training` record, whose time is summed over resumed segments.
    seconds: a wall-clock budget instead (agents.learning.budget; `budget` is then not used),
    capped at `cap` steps if given: a finished run of it is reused unless `fresh`
    (`finished_before`), any other trains afresh (a clock cannot be resumed)."""
    if seconds and not fresh:
        reused = finished_before(env_id, algo, seed, run_dir, hyperparams, randomize, seconds, cap)
        if reused is not None:
            return run_dir / "model.zip", reused
    fresh = fresh or bool(seconds)
    found = None if fresh else latest_checkpoint(run_dir / "checkpoints")
    start = found[0] if found else 0
    try:
        result = train(
            env_id,
            algo,
            timesteps=cap if seconds else budget,
            seed=seed,
            run_dir=run_dir,
            resume=not fresh,
            overwrite=fresh,
            progress=progress,
            hyperparams=hyperparams,
            randomize=randomize,
            budget=seconds,
            eval_episodes=20 if seconds else 10,
        )
    except TrainingInterrupted as stopped:  # keep the time of what the checkpoint holds
        record_segment(run_dir, start, stopped.result.timesteps, stopped.result.wall_s)
        raise
    train_s, timed = record_segment(run_dir, start, result.timesteps, result.wall_s)
    now = result.wall_s if result.timesteps > start else 0.0
    shown = result.timesteps if seconds else budget  # a time budget: the steps it took
    return result.model_path, Training(algo, shown, result.timesteps, train_s, timed, "", now)


def finished_before(env_id, algo, seed, run_dir, hyperparams, randomize, seconds, cap):
    """The `Training` record of a run in `run_dir` of a time budget of `seconds` capped at
    `cap` steps (or none) with these settings that was solved or trained its cap, which the
    check reuses instead of training again (`rundir.finished_run`), else None."""
    hp, steps, _ = budgets.budget_run(load_hyperparams(algo, env_id, hyperparams), cap)
    if randomize is not None:
        hp["randomize"] = randomize
    expected = dict(env_id=env_id, algo=algo, seed=seed, hyperparams=hp, n_timesteps=steps)
    expected["budget_s"] = float(seconds)
    train_s, trained = timing.recorded(run_dir)
    if not finished_run(run_dir, {**expected, "task": task_fingerprint(env_id)}, trained):
        return None
    return Training(algo, trained, trained, train_s, trained, "")


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
    report: Path | None = None,
    randomize: dict | None = None,
    seconds: float | None = None,
    diagnoses: list | None = None,
    refused: list | None = None,
    cap: int | None = None,
) -> list[Row]:
    """Every baseline, LQR and the trained agent on one environment (the run directory
    named in the rows relative to `report`, the report's directory; default `out`). The
    agent trains with `randomize` (agents.learning.randomization) if given; every agent is scored
    on the nominal env. seconds: a wall-clock budget (agents.learning.budget) instead of steps,
    capped at `cap` steps if given; diagnoses: a list the lines of a failed agent's
    diagnosis are appended to; refused: a list each agent not run is appended to
    (`Refused`, with its one-line reason)."""
    algo = algo or hparams.check_algo(env_id)
    heuristic = heuristic_of(env_id)
    plans = "plan" in task_of(env_id).hyperparams  # planning is declared where it pays
    rows, refused = [], [] if refused is None else refused
    for name in BASELINES:
        undeclared = {"heuristic": heuristic is None, "plan": not plans}.get(name)
        if undeclared:  # not declared: the task says where it pays
            what = "trajectory plan (hyperparams['plan'])" if name == "plan" else name
            refused.append(Refused(env_id, name, f"the task declares no {what}"))
            continue
        try:
            stats, eval_s, warm_s = learned.warm_evaluate(
                programs.evaluate, env_id, name, episodes, seed
            )
        except Unsupported as exc:  # it would be wrong here, and says why
            log(f"  {name:>9}: refused: {exc}")
            refused.append(Refused(env_id, name, f"refused: {' '.join(str(exc).split())}"))
            continue
        note = heuristic.description if name == "heuristic" else ""
        rows.append(Row(env_id, name, stats, eval_s, note, warmup_s=warm_s))
        log(f"  {name:>9}: {stats.summary()}")
    run_dir, budget, limit = run_plan(
        out, env_id, algo, seed, timesteps, seconds, cap, hyperparams, randomize
    )
    length = f"until solved, at most {limit}" if seconds else f"for {limit}"
    log(f"  training {algo.upper()} {length} in {run_dir} ...")
    lqr = not any(r.env_id == env_id and r.agent == "lqr" for r in refused)
    settings = describe(load_hyperparams(algo, env_id, hyperparams), lqr)
    log(f"  ({settings}; agents.learning.defaults)")
    model, training = train_timed(
        env_id, algo, budget, seed, run_dir, fresh, progress, hyperparams, randomize, seconds, cap
    )
    if not training.now_s:
        log("  reused the run on disk (--fresh trains afresh)")
    link = Path(os.path.relpath(run_dir, report or out)).as_posix()
    training = replace(training, run_dir=link)
    score = programs.evaluate
    stats, eval_s, warm_s = learned.warm_evaluate(score, env_id, str(model), episodes, seed)
    alone, lqr_note, _, _ = learned.alone_rows(programs, env_id, algo, model, episodes, seed, log)
    notes = (
        randomization.describe(randomize) if randomize else "",
        lqr_note,
        *learned.verdict_notes(run_dir, limit if seconds else None, stats),
        learned.resumed_note(run_dir),
    )
    rows.append(Row(env_id, algo, stats, eval_s, "; ".join(filter(None, notes)), training, warm_s))
    log(
        f"  {algo:>9}: {stats.summary()} ({training.timesteps:,} steps, "
        f"{training.train_s:.0f} s training)"
    )
    rate = min(r.stats.success_rate for r in rows[-1:] + alone)  # the agent alone counts
    lines = learned.diagnosis_lines(programs, env_id, model, rate, episodes, seed, plans, log)
    if diagnoses is not None:
        diagnoses.extend(lines)
    return rows + alone


def run_plan(out, env_id, algo, seed, timesteps, seconds, cap, hyperparams, randomize):
    """(run directory, step budget, the limit in words) of an agent: a time budget's run is
    named by its seconds ("600 s", or "600 s or 3,000,000 steps" where `cap` steps cap it),
    a step budget's by its steps."""
    budget = budget_of(env_id, algo, timesteps, hyperparams) if cap is None else cap
    tag = randomization.tag(randomize) + params.tag(env_id)
    if seconds:
        run_dir = learned.budget_run_dir(out, env_id, algo, seed, seconds, tag)
        return run_dir, budget, f"{seconds:g} s" + (f" or {cap:,} steps" if cap else "")
    return run_dir_of(out, env_id, algo, seed, budget, tag), budget, f"{budget:,} steps"


def budget_of(env_id: str, algo: str, timesteps: int | None, hyperparams) -> int:
    """The training budget: `timesteps`, else the hyperparameters' n_timesteps."""
    if timesteps is not None:
        return int(timesteps)
    return int(hparams.load(algo, env_id, hyperparams)["n_timesteps"])


def check_runs_on_disk(env_ids, algo, seed, out, timesteps, hyperparams, randomize=None) -> None:
    """Before any work: refuse (UserError) a run on disk that the job would resume with
    other settings than asked for (see `check_earlier_run`)."""
    for env_id in env_ids:
        name = algo or hparams.check_algo(env_id)
        budget = budget_of(env_id, name, timesteps, hyperparams)
        hp = load_hyperparams(name, env_id, hyperparams)
        if randomize is not None:
            hp["randomize"] = randomize
        tag = randomization.tag(randomize) + params.tag(env_id)
        run_dir = run_dir_of(out, env_id, name, seed, budget, tag)
        check_earlier_run(run_dir, budget, hp)
        check_fingerprint(run_dir, env_id)


def report_dir(
    out: Path, env_ids: list[str] | None, timesteps=None, seconds=None, randomize=None
) -> Path:
    """Where an invocation's report goes: `out` itself for the default set (every built-in
    env) with the tasks' budgets, else a directory of its own under `out` named by the env
    ids (or 'all') and the budget asked for (--timesteps N: '_Nsteps'; --budget S: '_Ss';
    --randomize and --params: their tags), so that checking systems one by one, or one
    system with another budget, never overwrites another invocation's report (the same
    command again updates its own). The trained runs are shared (out/train), so each is
    trained once whichever report uses it."""
    suffix = f"_{seconds:g}s" if seconds else f"_{timesteps}steps" if timesteps else ""
    suffix += randomization.tag(randomize) + params.tag(env_ids or register_envs())
    if not env_ids and not suffix:
        return out
    return out / (("+".join(env_slug(e) for e in env_ids) if env_ids else "all") + suffix)


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
    randomize: dict | None = None,
    seconds: float | None = None,
) -> list[Row]:
    """Check every environment (default: all of `envs.ENV_IDS`); write the report to
    `report_dir(out, env_ids)`. algo: the algorithm to train everywhere (default: per env,
    the task's `algo`). randomize: train with randomised parameters (agents.learning.randomization).
    seconds: train each agent until solved within this wall-clock budget (agents.learning.budget;
    a finished run is reused, any other trains afresh: a clock cannot be resumed). timesteps:
    train each for this many steps, to the end. With neither, each trains until solved
    within `declared.DEFAULT_SECONDS` and the steps its task declares, if it does
    (`declared.steps_cap`)."""
    given = list(env_ids or [])
    env_ids = given or list(register_envs())
    if not env_ids:
        raise ValueError("No environments to check: the `envs` package registers none.")
    env_ids = [check_env_id(e, lagrange=True) for e in env_ids]
    out = Path(out)
    report = report_dir(out, [check_env_id(e) for e in given], timesteps, seconds, randomize)
    timed = declared.seconds_of(timesteps, seconds)
    caps = {e: declared.steps_cap(e, algo, timesteps, seconds, hyperparams) for e in env_ids}
    if not (fresh or timed):  # a time budget's runs are reused only where finished, as they were
        check_runs_on_disk(env_ids, algo, seed, out, timesteps, hyperparams, randomize)
    set_torch_threads(DEFAULT_TORCH_THREADS)
    print(
        f"The report goes to {report}/ (trained runs: {out / 'train'}/). In the lines below, "
        "sd is the standard deviation of the return over the episodes; the report's "
        "intervals are 95 % confidence intervals of the mean return and the success rate.",
        file=sys.stderr,
    )
    start = time.perf_counter()
    rows: list[Row] = []
    diagnoses: list[str] = []
    refused: list[Refused] = []
    for i, env_id in enumerate(env_ids, 1):
        print(f"[{i}/{len(env_ids)}] {env_id}", file=sys.stderr, flush=True)
        log = lambda text: print(text, file=sys.stderr, flush=True)  # noqa: E731
        rows += check_env(
            env_id,
            algo,
            episodes,
            seed,
            out,
            timesteps,
            fresh,
            progress,
            log,
            hyperparams,
            report,
            randomize,
            timed,
            diagnoses,
            refused,
            caps[env_id],
        )
    total = time.perf_counter() - start
    diagnosis = "".join(f"- {line}\n" for line in diagnoses)
    diagnosis = diagnosis and f"\n## Where the trained agents missed\n\n{diagnosis}"
    text = report_text(rows, episodes, seed, total, refused) + diagnosis
    write_atomic(report / "results.md", text)
    write_csv(rows, report / "results.csv", refused)
    plot_comparison(rows, report / "comparison.png")
    print("\n".join(f"- {line}" for line in training_lines(rows)) + "\n")
    print(markdown_table(rows, refused) + "\n")
    print("\n".join(f"- {line}" for line in findings(rows)))
    print(f"\nTotal wall time {total:.0f} s. Report, CSV and plot in {report}/")
    return rows


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m agents.check",
        description="Check every environment with random, zero-torque and heuristic "
        "baselines, LQR and a short stable-baselines3 training; print a Markdown "
        "comparison (how episodes ended, 95 % intervals: Wilson on success, Student t on "
        "the mean return; 'A beats B' only where they separate) and write it with a CSV "
        "and a figure to --out. Training and evaluation times are reported apart, one-off "
        "compilation excluded; training time is kept with each run across resumes.",
    )
    parser.add_argument(
        "env_ids",
        nargs="*",
        help="Lagrange env ids or module:NS/Env-v0 (default: the built-in Lagrange envs)",
    )
    parser.add_argument(
        "--algo",
        help=f"train this ({', '.join(ALGOS)}) on every env "
        "(default: per env, the algorithm its task declares)",
    )
    parser.add_argument(
        "--hyperparams",
        metavar="FILE",
        help="YAML overriding the packaged hyperparameters "
        "(format of agents/learning/hyperparams/*.yml)",
    )
    parser.add_argument(
        "--episodes", type=positive_int, default=20, help="seeded episodes per agent"
    )
    parser.add_argument("--seed", type=seed_int, default=0, help="first episode's seed")
    parser.add_argument(
        "--timesteps",
        type=positive_int,
        help="train every env for this many steps, to the end (default: until solved, at "
        "most 10 minutes and the declared n_timesteps); see --fresh for what a budget other "
        "than a run on disk does",
    )
    parser.add_argument(
        "--budget",
        type=budget_arg,
        help=f"train each agent until solved ({RULE.replace('%', '%%')}) "
        "within this wall-clock time (600, 90s, 10m), keeping the model that met it (else "
        "the best evaluated; a re-run reuses a run that was solved or trained its step cap, "
        "and trains any other afresh); "
        "instead of --timesteps (agents.learning.budget); without either, each trains so "
        "for 10m, at most its declared n_timesteps",
    )
    parser.add_argument(
        "--out",
        default="runs/check",
        help="output directory: trained runs in OUT/train; the report in OUT for the default "
        "set of envs and budgets, else in a directory of its own named by the envs given "
        "(ids joined by '+', or 'all') and the budget asked for: OUT/ENV, OUT/ENV_5000steps "
        "(--timesteps), OUT/ENV_90s (--budget), OUT/all_5000steps; so a check with another "
        "budget keeps the earlier report beside it, and the same command again updates its own",
    )
    parser.add_argument(
        "--fresh",
        action="store_true",
        help="retrain the runs of this budget from scratch. Without it, each budget trains "
        "in a run directory of its own (--out/train/ENV/ALGO_seedS_Nsteps): a run of the "
        "same budget is resumed from its checkpoint (or reused when finished or solved), another "
        "budget starts a fresh run and keeps the earlier one, and a run of the same budget "
        "with other hyperparameters is refused with a message",
    )
    params.add_option(parser)
    randomization.add_option(
        parser,
        "the training envs",
        "; the run trains in a directory of its own, and every agent is scored on the nominal env",
    )
    parser.add_argument("--no-progress", action="store_true", help="hide progress bars")
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.algo is not None and args.algo not in ALGOS:
        parser.error(f"unknown algorithm {args.algo!r}; choose from {', '.join(ALGOS)}")
    try:
        env_ids = check_env_ids(args.env_ids, lagrange=True)
        writable_folder(args.out, "--out")
        randomize = randomization.parse_option(args.randomize)
        values = params.load_for(args.params, env_ids or register_envs())
        if args.hyperparams is not None:
            for env_id in env_ids or register_envs():
                hparams.load(args.algo or hparams.check_algo(env_id), env_id, args.hyperparams)
    except ValueError as exc:
        fail(parser, exc)
    try:
        with params.applied_all(values):
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
                randomize,
                args.budget,
            )
    except UserError as exc:
        fail(parser, exc)
    except TrainingInterrupted as stopped:
        print(
            f"Interrupted at {stopped.result.timesteps:,} steps; saved a checkpoint in "
            f"{stopped.result.run_dir}. Run the same command again to resume (the training "
            "time so far is kept with the run).",
            file=sys.stderr,
        )
        return stopped.exit_code
    except KeyboardInterrupt:  # Ctrl-C outside training: finished runs are on disk
        print(
            "Interrupted; the runs trained so far are kept (the same command reuses them).",
            file=sys.stderr,
        )
        return 130
    return 0


if __name__ == "__main__":
    plain_warnings()  # a command prints messages, not source lines
    sys.exit(main())
