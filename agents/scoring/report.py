"""The main job's report: 95 % confidence intervals, comparisons that claim only what the
episodes resolve, and the Markdown table, CSV and comparison figure of `agents.check`.

Intervals (95 %):
- success rate: Wilson's score interval (good coverage down to 0/n and n/n, where the
  normal-approximation interval collapses to a point);
- mean return: Student's t interval, mean +- t(0.975, n-1) s / sqrt(n). It is exact for
  normal returns and, at 20 episodes, covers closer to 95 % than the percentile bootstrap
  (seeded simulation, 2000 samples of 20: normal 0.95 against 0.92, exponential 0.91
  against 0.89, a 20 %/80 % bimodal mixture 0.93 against 0.92); it is also deterministic.

"A beats B" is said only where A's interval lies wholly above B's, on success rate first
and, where the success intervals overlap, on return. Two 95 % intervals that do not overlap
are a conservative test (each alone would resolve smaller differences); pairs that overlap
are reported as not resolved at this number of episodes.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..common import atomic_path, write_atomic
from .episodes import ENDINGS, EvalStats

LEVEL = 0.95
Z = 1.959963984540054  # the standard normal's 0.975 quantile


@dataclass(frozen=True)
class Interval:
    low: float
    high: float

    def above(self, other: Interval) -> bool:
        """True when this interval lies wholly above `other` (they separate)."""
        return self.low > other.high


def wilson_interval(successes: int, n: int, z: float = Z) -> Interval:
    """Wilson's score interval for a binomial proportion (95 % for the default z)."""
    if n < 1 or not 0 <= successes <= n:
        raise ValueError(f"Expected 0 <= successes <= n and n >= 1, got {successes}/{n}.")
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    # the interval holds p exactly; at p = 0 or 1 rounding alone would put it a hair outside
    return Interval(min(p, max(0.0, centre - half)), max(p, min(1.0, centre + half)))


def mean_interval(samples, level: float = LEVEL) -> Interval:
    """Student's t interval for the mean of `samples` (unbounded for a single sample)."""
    from scipy import stats

    x = np.asarray(samples, dtype=float)
    if x.size < 2:
        return Interval(-math.inf, math.inf)
    half = stats.t.ppf(0.5 + level / 2, x.size - 1) * x.std(ddof=1) / math.sqrt(x.size)
    return Interval(float(x.mean() - half), float(x.mean() + half))


def success_interval(stats: EvalStats) -> Interval:
    return wilson_interval(int(np.sum(stats.successes)), len(stats.successes))


def return_interval(stats: EvalStats) -> Interval:
    return mean_interval(stats.returns)


# ---- rows and comparisons ----------------------------------------------------------------
@dataclass(frozen=True)
class Training:
    """The trained agent's run: the algorithm, the budget asked for, the steps trained and
    the training time summed over the run's segments (`timed_steps` of them timed)."""

    algo: str
    budget: int
    timesteps: int
    train_s: float
    timed_steps: int
    run_dir: str  # relative to the report's directory
    now_s: float = 0.0  # of train_s, the time this invocation trained (0 for a reused run)


@dataclass(frozen=True)
class Row:
    env_id: str
    agent: str
    stats: EvalStats
    eval_s: float  # evaluating the episodes, after a one-episode warm-up
    note: str = ""
    training: Training | None = None
    warmup_s: float = 0.0  # the untimed first episode: one-off compilation and loading


@dataclass(frozen=True)
class Refused:
    """An agent not scored on an env, and why: it refused (LQR on a time-dependent model),
    or the task declares none (no heuristic, no plan)."""

    env_id: str
    agent: str
    reason: str


def beats(a: EvalStats, b: EvalStats) -> bool:
    """A's success interval above B's, or (those overlapping) A's return interval above B's."""
    sa, sb = success_interval(a), success_interval(b)
    if sa.above(sb):
        return True
    return not sb.above(sa) and return_interval(a).above(return_interval(b))


def _pct(stats: EvalStats) -> str:
    ci = success_interval(stats)
    return f"{stats.success_rate:.0%} [{ci.low:.0%}, {ci.high:.0%}]"


def _ret(stats: EvalStats) -> str:
    ci = return_interval(stats)
    return f"{stats.mean_return:.1f} [{ci.low:.1f}, {ci.high:.1f}]"


def compare(name_a: str, a: EvalStats, name_b: str, b: EvalStats) -> str:
    """One sentence: who beats whom on which measure, or that it is not resolved."""
    said: dict[str, list[str]] = {}  # "A beats B" -> the measures, with their intervals
    for measure, interval, show in (
        ("success rate", success_interval, _pct),
        ("return", return_interval, _ret),
    ):
        for (n1, s1), (n2, s2) in (((name_a, a), (name_b, b)), ((name_b, b), (name_a, a))):
            if interval(s1).above(interval(s2)):
                claim = f"{measure} ({show(s1)} vs {show(s2)})"
                said.setdefault(f"{n1} beats {n2}", []).append(claim)
    if said:
        return "; ".join(f"{who} on " + " and on ".join(how) for who, how in said.items())
    n = min(len(a.returns), len(b.returns))
    return (
        f"{name_a} vs {name_b}: not resolved at {n} episodes (success {_pct(a)} vs {_pct(b)}, "
        f"return {_ret(a)} vs {_ret(b)}: the 95 % intervals overlap)"
    )


def best_agents(mine: dict[str, EvalStats]) -> list[str]:
    """The agents no other agent beats (by `beats`), best point estimate first."""
    order = sorted(mine, key=lambda k: (-mine[k].success_rate, -mine[k].mean_return))
    best = [a for a in order if not any(beats(mine[b], mine[a]) for b in order if b != a)]
    return best or order[:1]


def findings(rows: list[Row]) -> list[str]:
    """Per environment: the agents nothing beats, LQR against the trained agent, and the
    trained agent against the zero and random baselines; each claim only where resolved."""
    out = []
    for env_id in dict.fromkeys(r.env_id for r in rows):
        mine = {r.agent: r.stats for r in rows if r.env_id == env_id}
        trained = [r.agent for r in rows if r.env_id == env_id and r.training is not None]
        best = best_agents(mine)
        if len(best) == 1:
            parts = [f"best: {best[0]} (no other agent beats it)"]
        else:
            parts = [f"best, not resolved between them: {', '.join(best)}"]
        for algo in trained:
            if "lqr" in mine:
                parts.append(compare("lqr", mine["lqr"], algo, mine[algo]))
            for baseline in ("zero", "random"):
                if baseline in mine:
                    parts.append(compare(algo, mine[algo], baseline, mine[baseline]))
        out.append(f"{env_id}:" + "".join(f"\n  - {p}" for p in parts))
    return out


# ---- table, header and CSV ---------------------------------------------------------------
def markdown_table(rows: list[Row], refused: list[Refused] = ()) -> str:
    """The table; each env's `refused` agents follow its rows, with their reason."""
    endings = " | ".join(f"ended: {e}" if e == ENDINGS[0] else e for e in ENDINGS)
    lines = [
        f"| environment | agent | success [95 % CI] | return [95 % CI] | {endings} | "
        "length | eval (s) | train (s) | note |",
        "|---|---|---|---|" + "---|" * len(ENDINGS) + "---|---|---|---|",
    ]
    for env_id in dict.fromkeys([r.env_id for r in rows] + [r.env_id for r in refused]):
        for r in (r for r in rows if r.env_id == env_id):
            counts = " | ".join(str(n) for n in r.stats.endings().values())
            train = "" if r.training is None else f"{r.training.train_s:.1f}"
            lines.append(
                f"| {r.env_id} | {r.agent} | {_pct(r.stats)} | {_ret(r.stats)} | {counts} | "
                f"{r.stats.mean_length:.0f} | {r.eval_s:.2f} | {train} | {r.note} |"
            )
        for r in (r for r in refused if r.env_id == env_id):
            why, blank = " ".join(r.reason.split()).replace("|", "\\|"), " |" * (len(ENDINGS) + 4)
            lines.append(f"| {r.env_id} | {r.agent} | not run |{blank} {why} |")
    return "\n".join(lines)


def training_lines(rows: list[Row]) -> list[str]:
    """Per environment: the algorithm and budget, steps trained, time and learning curve."""
    out = []
    for r in rows:
        t = r.training
        if t is None:
            continue
        timed = "" if t.timed_steps >= t.timesteps else f", {t.timed_steps:,} of them timed"
        out.append(
            f"{r.env_id}: {t.algo.upper()}, {t.budget:,} steps ({t.timesteps:,} trained in "
            f"{t.train_s:.0f} s{timed}; [learning curve]({t.run_dir}/learning_curve.png))"
        )
    return out


CSV_FIELDS = (
    "env_id agent episodes success_rate success_low success_high mean_return return_low "
    "return_high std_return n_success n_failure n_diverged n_time_limit mean_length eval_s "
    "algo budget timesteps train_s note"
).split()


def write_csv(rows: list[Row], path: Path, refused: list[Refused] = ()) -> None:
    """The rows, then the `refused` agents (no numbers; the note 'not run: REASON')."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(CSV_FIELDS)
    for r in rows:
        s, t = r.stats, r.training
        sc, rc = success_interval(s), return_interval(s)
        train = ["", "", "", ""] if t is None else [t.algo, t.budget, t.timesteps, t.train_s]
        writer.writerow(
            [r.env_id, r.agent, len(s.returns)]
            + [f"{v:.4f}" for v in (s.success_rate, sc.low, sc.high)]
            + [f"{v:.4f}" for v in (s.mean_return, rc.low, rc.high, s.std_return)]
            + list(s.endings().values())
            + [f"{s.mean_length:.1f}", f"{r.eval_s:.3f}"]
            + [f"{v:.2f}" if isinstance(v, float) else v for v in train]
            + [r.note]
        )
    for r in refused:
        empty = [""] * (len(CSV_FIELDS) - 3)
        writer.writerow([r.env_id, r.agent] + empty + [f"not run: {' '.join(r.reason.split())}"])
    write_atomic(path, buf.getvalue())


# ---- the comparison figure ---------------------------------------------------------------
KNOWN_COLOURS = {
    "random": "#9e9e9e",
    "zero": "#5f5f5f",
    "heuristic": "#2ca02c",
    "lqr": "#1f77b4",
    "plan": "#9467bd",
    "ppo": "#ff7f0e",
    "sac": "#d62728",
    "td3": "#8c564b",
}
SPARE_COLOURS = ("#e377c2", "#17becf", "#bcbd22", "#7f7f7f")


def agent_colours(rows: list[Row]) -> dict[str, str]:
    """One colour per agent name, the same in every environment's panels."""
    colours, spare = {}, iter(SPARE_COLOURS * 8)
    for agent in dict.fromkeys(r.agent for r in rows):
        colours[agent] = KNOWN_COLOURS.get(agent) or next(spare)
    return colours


def return_limits(intervals: list[Interval], means: list[float]) -> tuple[float, float]:
    """x limits for one environment's returns: every interval of the better half of the
    agents (by mean), widened to take in the others unless that would more than double the
    range; agents left outside are drawn at the edge with their value."""
    finite = [(m, i) for m, i in zip(means, intervals) if math.isfinite(i.low)]
    if not finite:
        finite = [(m, Interval(m, m)) for m in means]
    finite.sort(key=lambda p: -p[0])
    core = finite[: max(2, -(-len(finite) // 2))]
    low = min(min(i.low, m) for m, i in core)
    high = max(max(i.high, m) for m, i in core)
    span = max(high - low, 1e-9)
    for m, i in finite[len(core) :]:
        if min(i.low, m) >= low - span:
            low = min(low, i.low, m)
    span = max(high - low, 1e-3 * max(1.0, abs(high)))
    return low - 0.12 * span, high + 0.12 * span


def plot_comparison(rows: list[Row], path: Path) -> None:
    """Per environment, two panels: success rate with its Wilson interval (bars) and mean
    return with its t interval (points), values written beside them, one colour per agent."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    env_ids = list(dict.fromkeys(r.env_id for r in rows))
    colours = agent_colours(rows)
    n_agents = max(sum(r.env_id == e for r in rows) for e in env_ids)
    height = 0.5 + 0.32 * n_agents
    fig, axes = plt.subplots(
        len(env_ids),
        2,
        figsize=(11, 0.8 + height * len(env_ids)),
        squeeze=False,
        gridspec_kw={"width_ratios": [1, 1.3]},
    )
    for (ax_s, ax_r), env_id in zip(axes, env_ids):
        mine = [r for r in rows if r.env_id == env_id]
        _success_panel(ax_s, mine, colours)
        _return_panel(ax_r, mine, colours)
        ax_s.set_ylabel(env_id.split("/")[-1], fontsize=10, fontweight="bold")
    axes[-1][0].set_xlabel("success rate (bars), 95 % Wilson interval")
    axes[-1][1].set_xlabel("mean episode return, 95 % t interval (arrows: off the axis)")
    n = len(rows[0].stats.returns) if rows else 0
    fig.suptitle(f"agents on every environment ({n} episodes each)")
    fig.tight_layout()
    handles = [plt.Rectangle((0, 0), 1, 1, color=c) for c in colours.values()]
    fig.legend(
        handles,
        list(colours),
        loc="upper center",
        bbox_to_anchor=(0.5, 0.0),
        ncol=len(colours),
        frameon=False,
    )
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=100, bbox_inches="tight")
    plt.close(fig)


def _success_panel(ax, mine: list[Row], colours: dict[str, str]) -> None:
    y = np.arange(len(mine))
    rates = np.array([r.stats.success_rate for r in mine])
    cis = [success_interval(r.stats) for r in mine]
    err = np.array([[p - c.low, c.high - p] for p, c in zip(rates, cis)]).T
    ax.barh(
        y,
        rates,
        color=[colours[r.agent] for r in mine],
        xerr=err,
        capsize=3,
        error_kw={"elinewidth": 1, "ecolor": "black", "alpha": 0.6},
    )
    for yi, rate, ci in zip(y, rates, cis):
        inside = rate > 0.3  # the value at the bar's start, clear of the interval's whisker
        ax.text(
            0.02 if inside else ci.high + 0.02,
            yi,
            f"{rate:.0%}",
            va="center",
            ha="left",
            fontsize=9,
            fontweight="bold",
            color="white" if inside else "black",
        )
    ax.set_yticks(y, [r.agent for r in mine])
    ax.set_xlim(0, 1.15)
    ax.set_xticks([0, 0.25, 0.5, 0.75, 1.0], ["0", "25%", "50%", "75%", "100%"])
    ax.invert_yaxis()
    ax.grid(axis="x", alpha=0.3)


def _return_panel(ax, mine: list[Row], colours: dict[str, str]) -> None:
    y = np.arange(len(mine))
    means = [r.stats.mean_return for r in mine]
    cis = [return_interval(r.stats) for r in mine]
    low, high = return_limits(cis, means)
    for yi, r, m, ci in zip(y, mine, means, cis):
        colour = colours[r.agent]
        if m < low or m > high:  # off the axis: an arrow at the edge, with the value
            edge, ha = (low, "left") if m < low else (high, "right")
            ax.plot(edge, yi, "<" if m < low else ">", color=colour, ms=9, clip_on=False)
            ax.text(
                edge + (1 if m < low else -1) * 0.03 * (high - low),
                yi,
                f"{m:.1f}",
                va="center",
                ha=ha,
                fontsize=8,
            )
            continue
        lo, hi = max(ci.low, low), min(ci.high, high)
        ax.plot([lo, hi], [yi, yi], color=colour, lw=2.5, solid_capstyle="butt")
        ax.plot(m, yi, "o", color=colour, ms=7, mec="black", mew=0.6)
        ax.text(m, yi - 0.3, f"{m:.1f}", va="bottom", ha="center", fontsize=8)
    ax.set_xlim(low, high)
    ax.set_ylim(len(mine) - 0.4, -0.75)
    ax.set_yticks(y, [""] * len(mine))
    ax.grid(axis="x", alpha=0.3)


def report_text(
    rows: list[Row], episodes: int, seed: int, wall_s: float, refused: list[Refused] = ()
) -> str:
    """The Markdown report: what was run and how it is scored, the table (with the agents
    that were not run, and why), the findings."""
    trained = "\n".join(f"- {line}" for line in training_lines(rows))
    runs = [r.training for r in rows if r.training is not None]
    train_s, now_s = sum(t.train_s for t in runs), sum(t.now_s for t in runs)
    eval_s = sum(r.eval_s for r in rows)
    warm_s = sum(r.warmup_s for r in rows)
    notes = "\n".join(f"- {line}" for line in findings(rows))
    return (
        f"# Agents on every environment\n\n"
        f"{episodes} episodes per agent, seeded {seed}..{seed + episodes - 1} (the same starts "
        "for every agent). Success is the task's criterion at the last step; each episode "
        "ended in one way: success, failure (the task terminated it), diverged (the state "
        "left its bounds or became non-finite) or time limit (truncated without success). "
        "Intervals are 95 %: Wilson's score interval for the success rate, Student's t "
        'interval for the mean return. A finding says "A beats B" only where the two '
        "intervals do not overlap, and on which measure; otherwise it says the difference is "
        f"not resolved at {episodes} episodes.\n\n"
        "## Trained agents\n\nAlgorithm and budget per environment. Each budget trains in "
        "a run directory of its own: a run of the same budget on disk is resumed (or reused "
        "when finished), another budget starts a fresh run and keeps the earlier one, and a "
        "run with other hyperparameters is refused unless --fresh retrains it. Training time "
        "is stored with the run and summed over its resumed segments. PPO trains whole "
        "rollouts (n_steps x n_envs steps), so it may train a little past the budget.\n\n"
        f"{trained}\n\n"
        f"Time: training {train_s:.0f} s (stored with the runs; {now_s:.0f} s of it in this "
        f"run of the job), evaluation {eval_s:.1f} s, warm-up {warm_s:.1f} s "
        "(one untimed episode per agent first: numba kernels compiled or loaded, LQR "
        "designed, models loaded; counted in neither); this run of the job took "
        f"{wall_s:.0f} s.\n\n"
        f"{markdown_table(rows, refused)}\n\n## Findings\n\n{notes}\n\n"
        "![comparison](comparison.png)\n"
    )
