"""Train a stable-baselines3 agent on an environment: `python -m agents.train ENV_ID --algo ppo`.

Hyperparameters come from agents/learning/hyperparams/<algo>.yml (keyed by env id), overridden by a
file of the same format given with `--hyperparams`. A run directory holds config.yml, checkpoints/
(atomic; `--resume` continues from the newest, keeping the timestep count, the
learning-rate schedule and the evaluation schedule), model.zip and vecnormalize.pkl (atomic),
episodes.csv, eval.csv, evaluations.npz and learning_curve.png.

Ctrl-C (SIGINT) or SIGTERM stops training at the next environment step and saves the model,
its normalisation statistics and a checkpoint before exiting with 128 + the signal number
(130 for Ctrl-C); a second signal stops at once without saving. A directory that holds an
earlier run is only trained into with `--resume` (continue it) or `--overwrite` (start
afresh); only one process trains into a directory at a time (agents.learning.rundir).
The pieces, in agents.learning: hparams (hyperparameters to SB3's arguments), vecenv (the
envs), rundir (the run directory), callbacks (checkpoints, evaluations, the stop, the
learning loop), budget (the wall-clock budget).
"""

from __future__ import annotations

import argparse
import shlex
import signal
import sys
from dataclasses import dataclass, field
from pathlib import Path

import yaml
from stable_baselines3.common.base_class import BaseAlgorithm

from . import params
from .common import (
    DEFAULT_TORCH_THREADS,
    UserError,
    check_env_id,
    plain_warnings,
    positive_int,
    seed_int,
    set_torch_threads,
    task_of,
    trained_line,
    write_atomic,
)
from .learning import budget as budgets
from .learning import confirm, randomization
from .learning import solved as stops
from .learning.callbacks import (
    AtomicCheckpoint,
    GracefulStop,
    build_or_load,
    learn,
    save_final,
)
from .learning.curves import CurveLogger
from .learning.defaults import episode_steps
from .learning.fingerprint import task_fingerprint
from .learning.hparams import ALGOS, check_entries, load_hyperparams, off_policy
from .learning.rundir import (
    check_resume_randomize,
    default_run_dir,
    exclusive,
    prepare_run_dir,
    read_config,
    remove_stale_temporaries,
)
from .learning.vecenv import VECTORIZATIONS, make_envs
from .scoring import fresh


@dataclass
class TrainResult:
    run_dir: Path
    model_path: Path
    timesteps: int
    wall_s: float
    eval_mean: float | None
    eval_std: float | None
    success_rate: float | None
    model: BaseAlgorithm | None = field(default=None, repr=False)
    solved: dict | None = None  # budget runs: {seconds, timesteps, rule} when solved


class TrainingInterrupted(KeyboardInterrupt):
    """Training stopped on a signal after saving; `result` says what was saved and
    `exit_code` is the shell's 128 + signal number (130 for Ctrl-C)."""

    def __init__(self, result: TrainResult, signum: int):
        super().__init__(f"training interrupted by {signal.Signals(signum).name}")
        self.result = result
        self.signum = signum
        self.exit_code = 128 + signum


# ---- the work ----------------------------------------------------------------------------
def train(
    env_id: str,
    algo: str = "ppo",
    timesteps: int | None = None,
    seed: int = 0,
    n_envs: int | None = None,
    run_dir: str | Path | None = None,
    resume: bool = False,
    eval_freq: int | None = None,
    eval_episodes: int = 10,
    checkpoint_freq: int | None = None,
    vectorization: str = "auto",
    progress: bool = True,
    threads: int = DEFAULT_TORCH_THREADS,
    verbose: int = 0,
    hyperparams: str | Path | None = None,
    overwrite: bool = False,
    allow_missing_buffer: bool = False,
    randomize: dict | None = None,
    budget: float | None = None,
) -> TrainResult:
    """Train `algo` on `env_id`; return where the model is and how it evaluated.

    timesteps, n_envs: override the YAML's n_timesteps / n_envs. hyperparams: a YAML file
    in the format of agents/learning/hyperparams/<algo>.yml whose entries override the
    packaged ones.
    eval_freq and checkpoint_freq count environment steps over the whole run (default:
    total/10 but at least 2000, and total/5; with `budget`, agents.learning.budget's schedule). A
    directory holding an earlier run needs `resume` (continue from its newest checkpoint)
    or `overwrite` (delete it, start afresh); an off-policy checkpoint without its replay
    buffer is refused unless `allow_missing_buffer` (the run then goes on with an empty
    buffer). randomize: the
    hyperparameter `randomize` (agents.learning.randomization, e.g. {"inertial": 0.25}) overriding
    the YAML's; a resumed run without it keeps the one its config.yml records. budget:
    wall-clock seconds; train until solved or out of time (agents.learning.budget), `timesteps`
    then caps the steps (default: no cap; a "lin_X" learning rate then decays over the
    budget's time, agents.learning.budget.OverBudget).

    Raises UserError for problems with the arguments, the hyperparameters or the run
    directory (before anything is written), and TrainingInterrupted after saving when
    SIGINT or SIGTERM stopped the run."""
    env_id = check_env_id(env_id)
    hp, total, n_envs, decay = _checked_arguments(
        env_id, algo, timesteps, n_envs, eval_episodes, vectorization, hyperparams, budget
    )
    set_torch_threads(threads)
    run_dir = Path(run_dir) if run_dir is not None else default_run_dir(env_id, algo, seed)
    env_options = _randomization(run_dir, env_id, hp, randomize, resume)
    with exclusive(run_dir):
        remove_stale_temporaries(run_dir)
        config = _config(env_id, algo, seed, total, n_envs, vectorization, hyperparams, hp)
        config.update({"budget_s": float(budget)} if budget is not None else {})
        found = prepare_run_dir(run_dir, env_id, algo, resume, overwrite, config)
        config.update(params.record(env_id, env_options))  # randomize's ranges, --params
        write_atomic(run_dir / "config.yml", yaml.safe_dump(config, sort_keys=False))
        rollout = 0 if off_policy(algo) else int(hp.get("n_steps", 2048)) * n_envs
        options = dict(
            eval_freq=eval_freq
            or budgets.budget_eval_freq(
                total, hp["n_timesteps"], budget, off_policy(algo), rollout
            ),
            eval_episodes=eval_episodes,
            checkpoint_freq=checkpoint_freq or max(total // 5, 1),
            progress=progress,
            verbose=verbose,
            allow_missing_buffer=allow_missing_buffer,
            budget=budget,
            decay=decay,
        )
        return _run(env_id, algo, hp, total, n_envs, seed, vectorization, run_dir, found, **options)


def _config(env_id, algo, seed, total, n_envs, vectorization, hyperparams, hp) -> dict:
    """What a run trains, as config.yml records it."""
    return {
        "env_id": env_id,
        "algo": algo,
        "seed": seed,
        "n_timesteps": total,
        "n_envs": n_envs,
        "vectorization": vectorization,
        "hyperparams_file": None if hyperparams is None else str(hyperparams),
        "hyperparams": hp,
        "task": task_fingerprint(env_id),  # agents.check reuses only the same declaration
    }


def _checked_arguments(
    env_id, algo, timesteps, n_envs, eval_episodes, vectorization, hyperparams, budget
) -> tuple[dict, int, int, float | None]:
    """The run's hyperparameters, total timesteps, n_envs and the learning rate that decays
    over the budget (or None); UserError for a bad argument. A budget without a step count
    runs to the step cap with constant schedules, but for the learning rate's."""
    hp = load_hyperparams(algo, env_id, hyperparams)
    decay = None
    if budget is not None:  # the clock or success stops it, and the steps if given
        hp, timesteps, decay = budgets.budget_run(hp, timesteps)
    total = int(timesteps if timesteps is not None else hp["n_timesteps"])
    declared = int(hp.get("n_envs", 1))
    n_envs = int(n_envs if n_envs is not None else declared)
    for name, value in (("timesteps", total), ("n_envs", n_envs), ("eval_episodes", eval_episodes)):
        if value < 1:
            raise UserError(f"{name} must be a positive integer, got {value}.")
    if n_envs != declared and "batch_size" in hp and not off_policy(algo):
        # a rollout of other copies keeps its minibatches per epoch (as defaults.rollout)
        hp["batch_size"] = max(int(hp["batch_size"]) * n_envs // declared, 1)
    if vectorization not in VECTORIZATIONS:
        raise UserError(f"vectorization must be one of {VECTORIZATIONS}, got {vectorization!r}.")
    return hp, total, n_envs, decay


def _randomization(run_dir: Path, env_id: str, hp: dict, randomize, resume: bool) -> dict:
    """Put the run's `randomize` into `hp` (a resumed run without one keeps its record's;
    with one, it must match the record, as must --params) and return the env options it
    gives, checked before anything is written."""
    if randomize is None and resume:
        randomize = (read_config(run_dir).get("hyperparams") or {}).get("randomize")
    elif resume:  # another setting would rewrite the record of what the run trained on
        check_resume_randomize(run_dir, randomize)
    if resume:  # other --params would be recorded as if the run had always used them
        params.check_resume(run_dir, env_id)
    if randomize is not None:
        hp["randomize"] = check_entries({"randomize": randomize}, "randomize")["randomize"]
    return randomization.env_kwargs(env_id, hp.get("randomize"))


def _run(env_id, algo, hp, total, n_envs, seed, vectorization, run_dir, found, **o) -> TrainResult:
    """Build (or load) the model, learn up to `total` timesteps, save; see `train`."""
    ckpt_dir = run_dir / "checkpoints"
    # every episode of an evaluation at once, one batched step for all (as the confirmation)
    eval_envs = min(o["eval_episodes"], confirm.EPISODES)
    train_env, eval_env = make_envs(env_id, hp, n_envs, seed, vectorization, eval_envs)
    stop = GracefulStop()
    try:
        model = build_or_load(
            algo, hp, train_env, seed, found, ckpt_dir, o["verbose"], o["allow_missing_buffer"]
        )
        curves = CurveLogger(run_dir, f"{algo.upper()} on {env_id}", found[0] if found else None)
        checkpoint = AtomicCheckpoint(o["checkpoint_freq"], ckpt_dir, curves)
        # an evaluation's most vector steps: the episodes an eval env runs x the time limit
        steps = -(-o["eval_episodes"] // eval_envs) * episode_steps(env_id, task_of(env_id))
        clock = budgets.Clock(o["budget"] or float("inf"), steps, eval_envs)
        if o["decay"] is not None:  # the rate decays over the budget's time
            model.lr_schedule = budgets.OverBudget(o["decay"], clock)
        solved = None
        if o["budget"]:
            solved = stops.solved_stop(
                run_dir, clock, lambda model, k: fresh.confirm(model, env_id, hp, k)
            )
        evaluation = budgets.BudgetedEval(  # on the step schedule; in time for a budget
            eval_env,
            o["eval_freq"],
            clock,
            stop,
            n_eval_episodes=o["eval_episodes"],
            deterministic=True,
            callback_after_eval=budgets.AfterEvals(curves.after_eval, *[solved] * bool(solved)),
            log_path=str(curves.staging_dir),
            verbose=0,
        )
        if found is not None:
            evaluation.restore(run_dir / "evaluations.npz", found[0])
        clock.begin()  # a budget covers from here to the kept model (agents.learning.budget)
        learning = model.num_timesteps < total  # else a finished run, resumed
        with stop:  # from here to the last save a signal stops and saves instead of killing
            if learning:
                callbacks = [stop, clock, curves, evaluation, checkpoint]
                label = f"{algo.upper()} on {env_id}" if o["progress"] else ""
                time_left = clock.left if o["budget"] else None
                learn(model, total, callbacks, found is None, label, time_left)
            if stop.signum is not None:  # keep what the weights have learnt from, no more
                model.num_timesteps = stop.consistent_timesteps
                curves.truncate(model.num_timesteps)
            if learning:
                checkpoint.save()
            model_path = save_final(model, run_dir)
            if solved is not None and stop.signum is None:  # the best evaluated, kept
                stops.keep_best(evaluation, solved, run_dir)
            curves.close()
        wall = clock.elapsed()
    finally:
        train_env.close()
        eval_env.close()
    last = curves.evals[-1] if curves.evals else {}
    success = last.get("success_rate", "")
    result = TrainResult(
        run_dir=run_dir,
        model_path=model_path,
        timesteps=model.num_timesteps,
        wall_s=wall,
        eval_mean=float(last["mean_return"]) if last else None,
        eval_std=float(last["std_return"]) if last else None,
        success_rate=float(success) if success != "" else None,
        model=model,
        solved=None if solved is None else solved.solved,
    )
    if stop.signum is not None:
        raise TrainingInterrupted(result, stop.signum)
    return result


# ---- command line ------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m agents.train",
        description="Train a stable-baselines3 agent with the per-environment hyperparameters "
        "of agents/learning/hyperparams/<algo>.yml. Writes a run directory with checkpoints, the "
        "model, normalisation statistics and learning curves (CSV and PNG). Ctrl-C saves "
        "the model and a checkpoint, then exits with status 130; --resume continues.",
    )
    parser.add_argument("env_id", help="Gymnasium id, e.g. Lagrange/BeadOnRod-v1")
    parser.add_argument("--algo", default="ppo", help=f"one of {', '.join(ALGOS)}")
    parser.add_argument("--timesteps", type=positive_int, help="budget (default: YAML n_timesteps)")
    parser.add_argument(
        "--budget",
        type=budgets.budget_arg,
        help="wall-clock budget (600, 90s, 10m, 1.5h): train until the evaluated success "
        f"holds ({budgets.RULE.replace('%', '%%')}) or the time is spent; keeps the model that "
        "met it, else the best evaluated (agents.learning.budget). Not repeatable: use "
        "--timesteps for that",
    )
    parser.add_argument("--seed", type=seed_int, default=0)
    parser.add_argument(
        "--n-envs",
        type=positive_int,
        help="parallel envs (default: YAML n_envs); an on-policy minibatch scales with it, "
        "keeping the minibatches per epoch",
    )
    parser.add_argument(
        "--hyperparams",
        metavar="FILE",
        help="YAML file in the format of agents/learning/hyperparams/<algo>.yml; "
        "its entries override",
    )
    parser.add_argument("--run-dir", help="output directory (default runs/train/ENV/ALGO_seedS)")
    params.add_option(parser)
    randomization.add_option(
        parser, "the training envs", "; overrides the hyperparameter `randomize`"
    )
    parser.add_argument("--resume", action="store_true", help="continue from the newest checkpoint")
    parser.add_argument(
        "--overwrite",
        action="store_true",
        help="start afresh in a run directory that holds an earlier run (deletes its files)",
    )
    parser.add_argument(
        "--allow-missing-buffer",
        action="store_true",
        help="resume a SAC/TD3 checkpoint whose replay buffer is missing with an empty buffer",
    )
    parser.add_argument(
        "--eval-freq", type=positive_int, help="env steps between evaluations (whole run)"
    )
    parser.add_argument(
        "--eval-episodes", type=positive_int, help="per evaluation (default 10; 20 with --budget)"
    )
    parser.add_argument(
        "--checkpoint-freq", type=positive_int, help="env steps between checkpoints"
    )
    parser.add_argument(
        "--vectorization",
        choices=VECTORIZATIONS,
        default="auto",
        help="native: the env's batched vector_entry_point; dummy: SB3 DummyVecEnv",
    )
    parser.add_argument(
        "--threads",
        type=positive_int,
        default=DEFAULT_TORCH_THREADS,
        help="torch threads (1 is fastest for these small networks)",
    )
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Exit status: 0 done, 2 a usage error (one line on stderr), 128 + N stopped by signal N
    (130 for Ctrl-C) after saving, or 130 when interrupted before anything could be saved."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.algo not in ALGOS:
        parser.error(f"unknown algorithm {args.algo!r}; choose from {', '.join(ALGOS)}")
    try:
        env_id = check_env_id(args.env_id)
    except ValueError as exc:
        parser.error(str(exc))
    try:
        randomize = randomization.parse_option(args.randomize)
        with params.applied(env_id, args.params and params.load(args.params, env_id)):
            result = train(
                env_id,
                args.algo,
                args.timesteps,
                args.seed,
                args.n_envs,
                args.run_dir,
                args.resume,
                args.eval_freq,
                args.eval_episodes or (20 if args.budget else 10),
                args.checkpoint_freq,
                args.vectorization,
                progress=not args.no_progress,
                threads=args.threads,
                hyperparams=args.hyperparams,
                overwrite=args.overwrite,
                allow_missing_buffer=args.allow_missing_buffer,
                randomize=randomize,
                budget=args.budget,
            )
    except UserError as exc:
        print(f"{parser.prog}: error: {exc}", file=sys.stderr)
        return 2
    except TrainingInterrupted as stopped:
        given = list(sys.argv[1:] if argv is None else argv)
        again = [a for a in given if a != "--overwrite"] + ["--resume"] * ("--resume" not in given)
        if args.run_dir is None:
            again += ["--run-dir", str(stopped.result.run_dir)]
        print(
            f"Interrupted at {stopped.result.timesteps} steps; saved "
            f"{stopped.result.model_path} and a checkpoint. Continue with: "
            f"{parser.prog} {shlex.join(again)}",
            file=sys.stderr,
        )
        return stopped.exit_code
    except KeyboardInterrupt:
        print("Interrupted; nothing saved since the last checkpoint.", file=sys.stderr)
        return 130
    print(trained_line(args.algo, env_id, result))
    return 0


if __name__ == "__main__":
    plain_warnings()  # a command prints messages, not source lines
    sys.exit(main())
