"""PPO hyperparameter search with Optuna on a shared study: every process started with the
same --storage and --study joins one study, on one machine or on several that share it.

    python examples/optuna_search.py Lagrange/BeadOnRod-v1 --storage runs/optuna.log --trials 10 &
    python examples/optuna_search.py Lagrange/BeadOnRod-v1 --storage runs/optuna.log --trials 10 &
    wait

--storage is a journal file (Optuna's JournalFileBackend: safe for processes sharing a file
system) or an RDB URL (sqlite:///runs/optuna.db, postgresql://...). A trial writes its
hyperparameters as a YAML file in the format of agents/learning/hyperparams/ppo.yml and trains
through `agents.train` (what `python -m agents.train ENV --hyperparams FILE` runs), so the
task's own settings are the base; its value is the trained agent's mean return over
--episodes seeded episodes (`agents.evaluate`, seeds from 1000: not the training's). The best
trial's file trains the agent for good: `python -m agents.train ENV --hyperparams FILE`.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import optuna
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from agents.evaluate import evaluate  # noqa: E402
from agents.train import train  # noqa: E402


def storage_of(text: str):
    """An RDB URL as it is; any other text is a journal file."""
    if "://" in text:
        return text
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend

    return JournalStorage(JournalFileBackend(text))


def objective(env_id: str, timesteps: int, out: Path, seed: int, episodes: int):
    def run(trial: optuna.Trial) -> float:
        hp = {
            "learning_rate": trial.suggest_float("learning_rate", 1e-4, 3e-3, log=True),
            "gamma": trial.suggest_float("gamma", 0.95, 0.999),
            "n_steps": trial.suggest_categorical("n_steps", [128, 256, 512]),
        }
        run_dir = out / f"trial{trial.number}"
        run_dir.mkdir(parents=True, exist_ok=True)
        (run_dir.parent / f"trial{trial.number}.yml").write_text(yaml.safe_dump({env_id: hp}))
        trial.set_user_attr("worker", os.getpid())
        result = train(
            env_id,
            "ppo",
            timesteps,
            seed,
            run_dir=run_dir,
            progress=False,
            overwrite=True,
            hyperparams=run_dir.parent / f"trial{trial.number}.yml",
        )
        stats = evaluate(env_id, str(result.run_dir), episodes=episodes, seed=1000)
        trial.set_user_attr("success_rate", stats.success_rate)
        return float(stats.mean_return)

    return run


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env_id")
    parser.add_argument("--storage", required=True, help="journal file or RDB URL")
    parser.add_argument("--study", default="ppo", help="study name (default: ppo)")
    parser.add_argument("--trials", type=int, default=10, help="trials this process runs")
    parser.add_argument("--timesteps", type=int, default=50_000, help="budget per trial")
    parser.add_argument("--seed", type=int, default=0, help="training seed of every trial")
    parser.add_argument("--episodes", type=int, default=20, help="evaluation episodes")
    parser.add_argument("--out", type=Path, default=Path("runs/optuna"))
    args = parser.parse_args(argv)
    study = optuna.create_study(
        study_name=args.study,
        storage=storage_of(args.storage),
        direction="maximize",
        load_if_exists=True,
    )
    run = objective(args.env_id, args.timesteps, args.out / args.study, args.seed, args.episodes)
    study.optimize(run, n_trials=args.trials)
    print(f"best of {len(study.trials)} trials: {study.best_value:.1f} {study.best_params}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
