"""Train until solved, within a wall-clock budget.

`--budget 10m` (also `600`, `90s`, `1.5h`) trains until the evaluated success holds or the
time is spent, whichever comes first. The rule (`SOLVED_RATE`, `SOLVED_TIMES`): the
evaluation during training (`--eval-episodes`, 20 in this mode, on starts the training
never sees, every `budget_eval_freq` steps) reaches at least 80 % success at two
evaluations in a row. Every evaluation
that beats the best so far (success rate, then mean return) saves the model, its
normalisation statistics and config.yml into `best/` of the run directory, each file
atomically; at the end the final model is evaluated too (unless it just was), the run's
model.zip is the best one (`best/` keeps it too), and
`solved.json` records the seconds and env steps to success.

Without `--timesteps` a budget run has no step count to decay a schedule over, so
"lin_X" schedules are read as the constant X; with `--timesteps` too, the steps cap the
run and the schedules decay over them as usual.

Repeatability: a step budget (`--timesteps`) with the same seed trains the same agent on
the same machine (tests/agents/test_repeatable.py); a wall-clock budget cannot, because
where it stops depends on the machine's load. The stop at success is on a step schedule
(evaluations every `--eval-freq` steps), so two runs that both reach it stop at the same
step with the same agent.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import shutil
import time
from pathlib import Path

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

from ..common import atomic_path, write_atomic

SOLVED_RATE = 0.8
SOLVED_TIMES = 2
BUDGET_STEPS_CAP = 10**9
"""The step count a budget-only run is given (it stops on time or success first)."""
_UNITS = {"": 1.0, "s": 1.0, "m": 60.0, "min": 60.0, "h": 3600.0}


def parse_budget(text: str) -> float:
    """Seconds in '600', '90s', '10m', '1.5h'; ValueError saying what was expected."""
    match = re.fullmatch(r"\s*([0-9]*\.?[0-9]+)\s*(s|m|min|h)?\s*", str(text))
    if not match:
        raise ValueError(f"expected a time such as 600, 90s, 10m or 1.5h, got {text!r}")
    seconds = float(match.group(1)) * _UNITS[match.group(2) or ""]
    if not (math.isfinite(seconds) and seconds > 0):
        raise ValueError(f"expected a positive time, got {text!r}")
    return seconds


def budget_arg(text: str) -> float:
    """argparse type for `parse_budget`."""
    try:
        return parse_budget(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def budget_eval_freq(total: int, declared: int, budget: float | None) -> int:
    """Env steps between evaluations: a tenth of the run (at least 2,000); with a time
    budget, a thirtieth of the declared n_timesteps, at least 10,000 (the acrobot's 3M-step
    budget would otherwise evaluate first at 300k steps, past a 300 s budget here)."""
    if budget is None:
        return max(min(total, declared) // 10, 2000)
    return max(declared // 30, 10_000)


def constant_schedules(hp: dict) -> dict:
    """`hp` with every 'lin_X' schedule read as the constant X (see the module docstring)."""
    return {
        k: float(v[4:]) if isinstance(v, str) and v.startswith("lin_") else v
        for k, v in hp.items()
    }


class Clock(BaseCallback):
    """Stops training when `seconds` of wall-clock time have passed since it started."""

    def __init__(self, seconds: float):
        super().__init__()
        self.seconds = float(seconds)
        self.start = time.perf_counter()
        self.ran_out = False

    def _on_training_start(self) -> None:
        self.start = time.perf_counter()

    def elapsed(self) -> float:
        return time.perf_counter() - self.start

    def _on_step(self) -> bool:
        if self.elapsed() >= self.seconds:
            self.ran_out = True
            return False
        return True


class AfterEvals(BaseCallback):
    """Several callbacks after each evaluation (EvalCallback takes one); each sees the
    evaluation as its parent. Stops training if any asks to."""

    def __init__(self, *callbacks: BaseCallback):
        super().__init__()
        self.callbacks = callbacks

    def _init_callback(self) -> None:
        for c in self.callbacks:
            c.parent = self.parent
            c.init_callback(self.model)

    def _on_step(self) -> bool:
        return all([c.on_step() for c in self.callbacks])


class SolvedStop(BaseCallback):
    """After each evaluation: keep the best model in `run_dir/best`, and stop training once
    the success rate has been at least `rate` at `times` evaluations in a row (recording
    the time and steps in solved.json). `clock` gives the training's elapsed seconds."""

    def __init__(self, run_dir: Path, clock: Clock, rate=None, times=None):
        super().__init__()
        self.run_dir, self.clock = Path(run_dir), clock
        self.rate = float(SOLVED_RATE if rate is None else rate)
        self.times = int(SOLVED_TIMES if times is None else times)
        self.streak = 0
        self.best: tuple[float, float] | None = None
        self.solved: dict | None = None

    def _init_callback(self) -> None:
        if self.model.num_timesteps == 0:  # a fresh run: nothing of an earlier one counts
            (self.run_dir / "solved.json").unlink(missing_ok=True)
            shutil.rmtree(self.run_dir / "best", ignore_errors=True)

    def _on_step(self) -> bool:
        parent = self.parent
        successes = parent._is_success_buffer
        rate = float(np.mean(successes)) if successes else 0.0
        score = (rate, float(np.mean(parent.evaluations_results[-1])))
        if self.best is None or score > self.best:
            self.best = score
            self.save_best()
        self.streak = self.streak + 1 if rate >= self.rate else 0
        if self.streak >= self.times:
            self.solved = {
                "seconds": round(self.clock.elapsed(), 2),
                "timesteps": int(self.num_timesteps),
                "rule": f">= {self.rate:.0%} success at {self.times} evaluations in a row "
                f"of {len(successes)} episodes",
            }
            write_atomic(self.run_dir / "solved.json", json.dumps(self.solved, indent=1) + "\n")
            return False
        return True

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
        record = {"timesteps": int(self.num_timesteps), "success_rate": self.best[0],
                  "mean_return": self.best[1]}  # fmt: skip
        write_atomic(best / "best.json", json.dumps(record, indent=1) + "\n")


def keep_best(evaluation, solved: SolvedStop, run_dir: Path) -> None:
    """At the end of a budget run: evaluate the final model unless the last evaluation was
    of it (the last steps may have learnt the most; this evaluation comes after the clock),
    then make the best evaluated model the run's model.zip."""
    from stable_baselines3.common.callbacks import EvalCallback

    model = evaluation.model
    if solved.solved is None and evaluation.evaluations_timesteps[-1:] != [model.num_timesteps]:
        evaluation.num_timesteps = model.num_timesteps
        EvalCallback._on_step(evaluation)  # records it and offers it to `solved` as best
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
