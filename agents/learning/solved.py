"""The end of a budget run: when it counts as solved (`SolvedStop`: the stop rule, then the
confirmation on fresh starts, `agents.learning.confirm`) and which model it keeps
(`keep_best`, `publish_best`). The rule and the clock are `agents.learning.budget`'s."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

from ..common import atomic_path, write_atomic
from . import budget
from .budget import BudgetedEval, Clock


def solved_stop(run_dir: Path, clock: Clock, confirm) -> SolvedStop:
    """The stop of a budget run: the rule, then `confirm(model, attempt) -> record` of its
    candidates on fresh starts (the caller's: `agents.scoring.fresh.confirm` for training)."""
    return SolvedStop(run_dir, clock, confirm=confirm)


class SolvedStop(BaseCallback):
    """After each evaluation: keep the best model in `run_dir/best`; once the success rate
    has been at least `rate` at `times` evaluations in a row, the evaluated model is a
    candidate, and `confirm(model, attempt)` (agents.learning.confirm) scores it on fresh
    starts: a confirmed candidate stops training (solved.json records the time, the steps
    and the confirmation) and is the model kept; one that is not confirmed does not stop
    it (each later evaluation at >= `rate` makes a new candidate while the streak holds).
    Every confirmation is recorded in confirmations.json. Without `confirm` the streak
    alone stops training (the rule before 2026-11-27).

    The model kept is never simply the best single evaluation, the luckiest of a run (the
    Segway's seed 0 kept a model that scored 100 % once between evaluations of 35-55 %, 70 %
    on 40 fresh starts): a candidate measured on the confirmation's many episodes ranks
    above every model measured on one evaluation's, and among those by its confirmed rate.
    `clock` gives the training's elapsed seconds (and, with `confirm`, whether a
    confirmation still fits the budget)."""

    def __init__(self, run_dir: Path, clock: Clock, rate=None, times=None, confirm=None):
        super().__init__()
        self.run_dir, self.clock = Path(run_dir), clock
        self.rate = float(budget.SOLVED_RATE if rate is None else rate)
        self.times = int(budget.SOLVED_TIMES if times is None else times)
        # (model, attempt) -> a record with "passed" (agents.scoring.fresh.confirm)
        self.confirm = confirm
        self.streak = 0
        self.best: tuple[float, float, float] | None = None  # (confirmed?, rate, return)
        self.solved: dict | None = None
        self.confirmations: list[dict] = []
        self.confirm_s = 0.0  # the last call's confirmation seconds (read by AfterEvals)

    def _init_callback(self) -> None:
        if self.model.num_timesteps == 0:  # a fresh run: nothing of an earlier one counts
            (self.run_dir / "solved.json").unlink(missing_ok=True)
            (self.run_dir / "confirmations.json").unlink(missing_ok=True)
            shutil.rmtree(self.run_dir / "best", ignore_errors=True)

    def _on_step(self) -> bool:
        parent = self.parent
        successes = parent._is_success_buffer
        rate = float(np.mean(successes)) if successes else 0.0
        mean = float(np.mean(parent.evaluations_results[-1]))
        self.streak = self.streak + 1 if rate >= self.rate else 0
        self.confirm_s = 0.0
        record = None
        if self.streak >= self.times and self.confirm is not None:
            if not self.clock.may_confirm():  # no time left to confirm it
                self.clock.ran_out = True
                self._offer((0.0, rate, mean))
                return False
            record = self.confirm(self.model, len(self.confirmations))
            record["timesteps"] = int(self.num_timesteps)
            self.confirm_s = float(record.get("seconds", 0.0))
            self.confirmations.append(record)
            path = self.run_dir / "confirmations.json"
            write_atomic(path, json.dumps(self.confirmations, indent=1) + "\n")
        candidate = self.streak >= self.times and (record is None or record["passed"])
        score = (1.0, record["rate"], mean) if record is not None else (0.0, rate, mean)
        self._offer(score, force=candidate)
        if candidate:
            rule = (
                f">= {self.rate:.0%} success at {self.times} evaluations in a row of "
                f"{len(successes)} episodes"
            )
            if record is not None:
                rule += (
                    f", then >= {record['needed']} of {record['episodes']} fresh "
                    "episodes (agents.learning.confirm)"
                )
            self.solved = {
                "seconds": round(self.clock.elapsed(), 2),
                "timesteps": int(self.num_timesteps),
                "rule": rule,
                **({"confirmed": record} if record is not None else {}),
            }
            write_atomic(self.run_dir / "solved.json", json.dumps(self.solved, indent=1) + "\n")
            return False
        return True

    def _offer(self, score: tuple, force: bool = False) -> None:
        """Keep the model just evaluated if `score` beats the best so far (or `force`)."""
        if self.best is None or score > self.best or force:
            self.best = score
            self.save_best()

    def save_best(self) -> None:
        best = self.run_dir / "best"
        best.mkdir(exist_ok=True)
        vecnorm = self.model.get_vec_normalize_env()
        if vecnorm is not None:
            with atomic_path(best / "vecnormalize.pkl") as tmp:
                vecnorm.save(tmp)
        shutil.copyfile(self.run_dir / "config.yml", best / "config.yml.tmp")
        (best / "config.yml.tmp").replace(best / "config.yml")
        with atomic_path(best / "model.zip") as tmp:
            self.model.save(tmp)
        record = {
            "timesteps": int(self.num_timesteps),
            "success_rate": self.best[1],
            "mean_return": self.best[2],
            "measured_on": "confirmation" if self.best[0] else "evaluation",
        }
        write_atomic(best / "best.json", json.dumps(record, indent=1) + "\n")


def keep_best(evaluation: BudgetedEval, solved: SolvedStop, run_dir: Path) -> None:
    """At the end of a budget run: evaluate the final model unless the last evaluation was
    of it (the last steps may have learnt the most; the clock kept time for it), then make
    the best evaluated model the run's model.zip. Where the evaluation would no longer end
    within the budget (it took longer than measured before) and an evaluated model exists,
    it is not started: that one is kept."""
    model, clock = evaluation.model, evaluation.clock
    fits = solved.best is None or clock.left() >= clock.evaluation_s() + clock.records_s
    evaluated = evaluation.evaluations_timesteps[-1:] == [model.num_timesteps]
    if solved.solved is None and not evaluated and evaluation.of_updates != clock.updates:
        if fits:
            evaluation.num_timesteps = model.num_timesteps
            evaluation.timed()  # records it and offers it to `solved` as best
    if solved.best is not None:
        publish_best(run_dir)


def publish_best(run_dir: Path) -> bool:
    """Copy best/model.zip (and its statistics) over the run's model.zip, atomically;
    False where there is no best model."""
    best = Path(run_dir) / "best"
    if not (best / "model.zip").exists():
        return False
    for name in ("vecnormalize.pkl", "model.zip"):  # the model last, as every save does
        if (best / name).exists():
            with atomic_path(Path(run_dir) / name) as tmp:
                shutil.copyfile(best / name, tmp)
    return True
