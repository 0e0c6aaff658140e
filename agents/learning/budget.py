"""Train until solved, within a wall-clock budget.

`--budget 10m` (also `600`, `90s`, `1.5h`) trains until the evaluated success holds or the
time is spent, whichever comes first. The rule (`SOLVED_RATE`, `SOLVED_TIMES`): the
evaluation during training (`--eval-episodes`, 20 in this mode, on starts the training
never sees, every `budget_eval_freq` steps) reaches at least 80 % success at three
evaluations in a row (two let agents through whose success on fresh starts was 65-75 %:
with 20 episodes each, a 70 % agent passes two in a row at 6 % of its evaluation pairs, and
runs make dozens; three, at 1.3 %, cost an agent at 95 % one evaluation more), and the model
that met it is then confirmed on fresh starts (`agents.learning.confirm`: at least 92 % of
200; one that is not confirmed does not stop training). Every evaluation
that beats the best so far (success rate, then mean return; a candidate measured on a
confirmation's episodes ranks above any single evaluation) saves the model, its
normalisation statistics and config.yml into `best/` of the run directory, each file
atomically; a run that is solved keeps the confirmed model;
one that runs out of time evaluates the final model too (unless its weights just were)
and keeps the best one. The run's model.zip is the kept one (`best/` holds it too), and
`solved.json` records the seconds and env steps to success.

What the budget covers: the run from the start of training (the envs and the model made,
matplotlib imported) to the kept model: the training steps and updates, the evaluations,
the final evaluation, the checkpoint and every save. The run's `wall_s` (the report's
training time) is that span, and it ends within the budget: at each step the `Clock` keeps
back what must still follow a stop, each part measured in the run itself (the final
evaluation at its longest, the last evaluation's time per step scaled to episodes that all
run to the time limit, plus the most its records took; the saves, twice that; the time to
its next check, the update phase where one comes first). An evaluation that would not end
in time is not started (training stops, and the final evaluation evaluates that model);
one after which there is no time for another ends training at the model it evaluated. What
can still go past is an end slower than measured (the load rising); on a loaded 2-core
machine the runs measured ended 0.05-3 s before their budgets (docs/learning.md). The
estimate is on the safe side, so a run may end up to about one evaluation early where
episodes end before the time limit; a budget shorter than the end itself (a few seconds)
cannot be met.

Without `--timesteps` a budget run has no step count to decay a schedule over, so its
learning rate's "lin_X" decays over the budget's time instead (`OverBudget`: X times the
share of the budget left, never below `DECAY_FLOOR` x X), and the other "lin_X"
schedules are read as the constant X; with `--timesteps` too, the steps cap the run and
the schedules decay over them as usual. A run that is solved early stops while its rate is
still high; one that trains to the end of its budget settles.

Repeatability: a step budget (`--timesteps`) with the same seed trains the same agent on
the same machine (tests/agents/test_budget.py); a wall-clock budget cannot: where it stops
depends on the machine's load, and its learning rate decays over the budget's time, so two
runs of the same seed differ from their first update on (docs/learning.md, "Repeatability").
"""

from __future__ import annotations

import argparse
import math
import re
import time

from stable_baselines3.common.callbacks import BaseCallback, EvalCallback

from . import confirm as confirmation
from .callbacks import ScheduledEval

SOLVED_RATE = 0.8
SOLVED_TIMES = 3
RULE = (
    f">= {SOLVED_RATE:.0%} success at {SOLVED_TIMES} evaluations in a row, then >= "
    f"{confirmation.RATE:.0%} of {confirmation.EPISODES} fresh starts"
)
"""The stop rule, in words (the command lines' help)."""
BUDGET_STEPS_CAP = 10**9
"""The step count a budget-only run is given (it stops on time or success first)."""
RECORDS_S = 0.75
"""What an evaluation's records and saves (the curves plotted, the best model saved) are
taken to cost until one is measured; the saves at the end are counted as two of them."""
WARMUP_STEPS, MEAN_OF_STEPS = 10, 100
"""The first training steps, whose times the mean step time leaves out (the first calls of
torch and the env take several times a step's time), and the steps after them it needs
before it is used (a few steps preempted under load would make it several times a step's)."""
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


def budget_eval_freq(
    total: int, declared: int, budget: float | None, off_policy: bool = False, rollout: int = 0
) -> int:
    """Env steps between evaluations: a tenth of the run (at least 2,000); with a time
    budget, a thirtieth of the declared n_timesteps, so that the stop rule's three
    evaluations in a row take a tenth of them (a tenth of the acrobot's 3M steps would put
    its first evaluation past a 300 s budget here), at least 10,000 for an on-policy
    learner (PPO trains 3-6k steps a second here: an evaluation of 20 episodes every 2-3 s
    of training would take as long as the training) and 1,000 for an off-policy one
    (50-100 steps a second here, one gradient step per env step: 10,000 steps would be 2-3
    minutes between evaluations, most of a short budget). `rollout`: an on-policy
    learner's steps per update (n_steps x n_envs), a floor in both cases: its weights
    change once a rollout, so a shorter interval evaluates the same weights twice (the
    three-link arm example's 64 copies x 256 steps: 16,384 steps, 1.6 evaluations a
    rollout at 10,000)."""
    if budget is None:
        return max(min(total, declared) // 10, 2000, rollout)
    return max(declared // 30, 1_000 if off_policy else 10_000, rollout)


DECAY_FLOOR = 0.05
"""The learning rate at the end of a budget, as a fraction of its start (`OverBudget`)."""


class OverBudget:
    """A learning rate "lin_X" in a budget run: X times the share of the budget's time left
    on `clock`, never below DECAY_FLOOR x X. Pickled without its clock (SB3 rebuilds a
    loaded model's schedule from its constant learning rate; a resumed run sets a new one)."""

    def __init__(self, start: float, clock: Clock | None = None):
        self.start, self.clock = float(start), clock

    def __call__(self, progress_remaining: float) -> float:
        clock = self.clock
        if clock is None or not math.isfinite(clock.seconds):
            return self.start
        return self.start * max(clock.left() / clock.seconds, DECAY_FLOOR)

    def __getstate__(self) -> dict:
        return {"start": self.start}

    def __setstate__(self, state: dict) -> None:
        self.start, self.clock = float(state["start"]), None


def decaying_rate(hp: dict) -> float | None:
    """X where `hp`'s learning rate is the schedule "lin_X", else None."""
    rate = hp.get("learning_rate")
    return float(rate[4:]) if isinstance(rate, str) and rate.startswith("lin_") else None


def constant_schedules(hp: dict) -> dict:
    """`hp` with every 'lin_X' schedule read as the constant X (see the module docstring)."""
    return {
        k: float(v[4:]) if isinstance(v, str) and v.startswith("lin_") else v for k, v in hp.items()
    }


def budget_run(hp: dict, timesteps: int | None) -> tuple[dict, int | None, float | None]:
    """A budget run's hyperparameters, step count and the rate that decays over its time:
    with `timesteps`, those steps and `hp` as they are; without, `BUDGET_STEPS_CAP`, every
    "lin_X" read as the constant X, and X the learning rate's (None: no "lin_" rate)."""
    if timesteps is not None:
        return hp, timesteps, None
    return constant_schedules(hp), BUDGET_STEPS_CAP, decaying_rate(hp)


class Clock(BaseCallback):
    """Stops training early enough that the run ends within `seconds` of `begin()`: at each
    step it keeps back what still has to come after the stop (`after_s`: the final
    evaluation and the saves) and the time to its next check (a step, and the update phase
    where one comes first). Evaluations report their durations to it (`BudgetedEval`) and
    ask it whether they may start (`may_evaluate`) and whether training may go on after
    them (`may_go_on`).

    eval_steps: the most vector steps one evaluation can take (its episodes per eval env x
    the time limit): a measured evaluation's time per step is scaled to it, since the next
    one may run its episodes longer. eval_envs: the envs an evaluation steps at once."""

    def __init__(self, seconds: float, eval_steps: int = 0, eval_envs: int = 1):
        super().__init__()
        self.seconds = float(seconds)
        self.eval_steps, self.eval_envs = int(eval_steps), int(eval_envs)
        self.start: float | None = None
        self.ran_out = False
        self.eval_step_s: float | None = None  # an evaluation's seconds per vector step
        self.records_s = RECORDS_S  # the most an evaluation's records and saves took
        self.update_s = 0.0  # the longest update phase (gradient steps between rollouts)
        self.confirm_s: float | None = None  # the longest confirmation
        self.updates = 0  # update phases so far: the weights change only there
        self._aside = 0.0  # seconds in evaluations and updates, not in training steps
        self._stepping = [0.0, 0]  # seconds between checks (less the above), and how many
        self._check: tuple[float, float] | None = None  # the last check's time and _aside
        self._rollout_end: float | None = None

    def begin(self) -> float:
        """Start the clock (the start of training); returns the start's perf_counter. With a
        budget, matplotlib is imported first (`load_plotting`)."""
        if math.isfinite(self.seconds):
            load_plotting()
        self.start = time.perf_counter()
        return self.start

    def _on_training_start(self) -> None:
        if self.start is None:
            self.begin()

    def elapsed(self) -> float:
        return 0.0 if self.start is None else time.perf_counter() - self.start

    def left(self) -> float:
        return self.seconds - self.elapsed()

    def step_s(self) -> float:
        """Mean seconds per training vector step (evaluations and updates left out)."""
        seconds, count = self._stepping
        return seconds / (count - WARMUP_STEPS) if count >= WARMUP_STEPS + MEAN_OF_STEPS else 0.0

    def evaluation_s(self) -> float:
        """What an evaluation will take: the measured seconds per step (until one is
        measured, a training step's: both step the envs and run the policy once) times the
        most steps it can take, plus its records and saves."""
        per_step = self.eval_step_s if self.eval_step_s is not None else self.step_s()
        return per_step * self.eval_steps + self.records_s

    def saves_s(self) -> float:
        """The saves after the stop (checkpoint, model, the best model published, the
        curves written): about two evaluations' records."""
        return 2.0 * self.records_s

    def after_s(self) -> float:
        """What follows a stop at a model not evaluated yet: its evaluation, the saves."""
        return self.evaluation_s() + self.saves_s()

    def may_evaluate(self) -> bool:
        """Whether an evaluation started now ends in time for the saves after it (training
        stops right after it where it leaves no room for another; see `may_go_on`)."""
        return self.left() > self.evaluation_s() + self.saves_s()

    def may_go_on(self) -> bool:
        """Whether training may go on to its next check and still end within the budget."""
        if self.left() > self.after_s() + self._next_check_s():
            return True
        self.ran_out = True
        return False

    def evaluated(self, seconds: float, records_s: float, lengths) -> None:
        """An evaluation took `seconds`, `records_s` of them in its records and saves, and
        ran episodes of `lengths` steps on `eval_envs` envs at once."""
        self._aside += seconds
        # the most any took: the first draws the learning curve, which later ones do only
        # every curves.PLOT_SECONDS, and the end draws it again (a third of a second each)
        self.records_s = records_s if self.eval_step_s is None else max(self.records_s, records_s)
        # at least its longest episode, and its steps shared evenly: a lower bound on the
        # vector steps it took, so its time per step is not underestimated
        steps = max(max(lengths, default=1), math.ceil(sum(lengths) / self.eval_envs), 1)
        self.eval_step_s = max(seconds - records_s, 0.0) / steps

    def confirmed(self, seconds: float) -> None:
        """A confirmation (agents.learning.confirm) took `seconds` (0: none ran)."""
        if seconds > 0:
            self._aside += seconds
            self.confirm_s = max(self.confirm_s or 0.0, seconds)

    def may_confirm(self) -> bool:
        """Whether a confirmation (agents.learning.confirm) ends in time for the saves: its
        time is the longest measured, until one is an evaluation's at its longest. A
        confirmation steps all its episodes at once, one batched step per time step, where
        an evaluation steps a few envs over several episodes each: measured 0.26-0.49 s for
        200 episodes against evaluations of seconds (an evaluation's time per episode
        times 200, the estimate first used, refused a confirmation with 46 s left)."""
        need = self.confirm_s if self.confirm_s is not None else self.evaluation_s()
        return self.left() > need + self.saves_s()

    def _on_rollout_end(self) -> None:
        self._rollout_end = time.perf_counter()

    def _on_rollout_start(self) -> None:
        if self._rollout_end is not None:
            update = time.perf_counter() - self._rollout_end
            self.update_s = max(self.update_s, update)
            self._aside += update
            self.updates += 1

    def _next_check_s(self) -> float:
        """Seconds to the next check: a step, and before it an update if this step ends
        the rollout (PPO says so; off-policy learners may update after any step)."""
        n, of = self.locals.get("n_steps"), self.locals.get("n_rollout_steps")
        ends_rollout = n is None or of is None or n + 1 >= of
        return self.step_s() + (self.update_s if ends_rollout else 0.0)

    def _on_step(self) -> bool:
        now = time.perf_counter()
        if self._check is not None:  # from the second check on: a step's time
            if self._stepping[1] >= WARMUP_STEPS:
                self._stepping[0] += max(now - self._check[0] - (self._aside - self._check[1]), 0)
            self._stepping[1] += 1
        self._check = (now, self._aside)
        return self.may_go_on()


class BudgetedEval(ScheduledEval):
    """ScheduledEval that reports its durations to `clock`, is not started where it would
    not end in time (training stops there instead, and the final evaluation, `keep_best`,
    evaluates the same model), and stops training after it where the time left would not
    cover training on and another evaluation (the model kept is then the one evaluated)."""

    def __init__(self, eval_env, every: int, clock: Clock, stop=None, **kw):
        super().__init__(eval_env, every, stop, **kw)
        self.clock = clock
        self.of_updates = -1  # the clock's update count at the last evaluation

    def _on_step(self) -> bool:
        if not self.due():
            return True
        if not self.clock.may_evaluate():
            self.clock.ran_out = True
            return False  # the final evaluation (keep_best) evaluates this model
        # with too little time left for another, training stops at the model evaluated
        return self.timed() and self.clock.may_go_on()

    def timed(self) -> bool:
        """Evaluate now, and tell the clock how long it took."""
        start, self.of_updates = time.perf_counter(), self.clock.updates
        go_on = EvalCallback._on_step(self)
        records = getattr(self.callback, "seconds", 0.0)
        confirm_s = getattr(self.callback, "confirm_s", 0.0)
        lengths = self.evaluations_length[-1] if self.evaluations_length else ()
        self.clock.evaluated(time.perf_counter() - start - confirm_s, records, lengths)
        self.clock.confirmed(confirm_s)
        return go_on


class AfterEvals(BaseCallback):
    """Several callbacks after each evaluation (EvalCallback takes one); each sees the
    evaluation as its parent. Stops training if any asks to."""

    def __init__(self, *callbacks: BaseCallback):
        super().__init__()
        self.callbacks = callbacks
        self.seconds = 0.0  # the last call's, its confirmation left out
        self.confirm_s = 0.0  # the last call's confirmation (agents.learning.confirm)

    def _init_callback(self) -> None:
        for c in self.callbacks:
            c.parent = self.parent
            c.init_callback(self.model)

    def _on_step(self) -> bool:
        start = time.perf_counter()
        go_on = all([c.on_step() for c in self.callbacks])
        self.confirm_s = sum(getattr(c, "confirm_s", 0.0) for c in self.callbacks)
        self.seconds = time.perf_counter() - start - self.confirm_s  # read by BudgetedEval
        return go_on


def load_plotting() -> None:
    """Import matplotlib (a second or more under load, once per process) before the clock
    starts: the first evaluation's records would otherwise take several times the later
    ones', and the clock, which keeps back what the last records took, would stop early."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot  # noqa: F401
