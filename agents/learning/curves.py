"""Learning curves: training episodes and periodic evaluations as CSV, plotted to PNG.

Both files are rewritten atomically whenever a checkpoint or evaluation is made, so a killed
run leaves them consistent with its last checkpoint; a resumed run reads them back and drops
the rows recorded after that checkpoint. The plot is redrawn at every checkpoint, at the end,
and after an evaluation at most every `PLOT_SECONDS` (drawing it takes about a third of a
second, longer than an evaluation of many tasks, and a run may evaluate every few seconds).
"""

from __future__ import annotations

import csv
import io
import os
import time
from pathlib import Path

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback, EvalCallback

from ..common import atomic_path, write_atomic

EPISODE_FIELDS = ("timesteps", "return", "length", "is_success")
EVAL_FIELDS = ("timesteps", "mean_return", "std_return", "success_rate", "mean_length", "wall_s")
PLOT_SECONDS = 30.0
"""The least time between two plots drawn after evaluations."""


def read_rows(path: Path, up_to_timesteps: int | None = None) -> list[dict]:
    """Rows of a curve CSV (empty if missing), keeping only timesteps <= up_to_timesteps."""
    if not path.exists():
        return []
    with open(path, newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    if up_to_timesteps is not None:
        rows = [r for r in rows if int(r["timesteps"]) <= up_to_timesteps]
    return rows


def write_rows(path: Path, fields: tuple[str, ...], rows: list[dict]) -> None:
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=fields, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    write_atomic(path, buf.getvalue())


class CurveLogger(BaseCallback):
    """Records every finished training episode and, through `after_eval`, each evaluation.

    Pass `logger.after_eval` as EvalCallback's `callback_after_eval` and
    `logger.staging_dir` as its `log_path` (its evaluations.npz, which SB3 writes in place,
    is then moved next to the CSVs atomically); call `flush()` to write the CSVs and plot."""

    def __init__(self, run_dir: Path, title: str, resume_from: int | None = None):
        super().__init__()
        self.run_dir = run_dir
        self.staging_dir = run_dir / ".staging"  # EvalCallback's log_path (see _AfterEval)
        self.episodes_csv = run_dir / "episodes.csv"
        self.eval_csv = run_dir / "eval.csv"
        self.plot_png = run_dir / "learning_curve.png"
        self.title = title
        cut = resume_from if resume_from is not None else -1  # fresh run: drop stale rows
        self.episodes = read_rows(self.episodes_csv, cut)
        self.evals = read_rows(self.eval_csv, cut)
        self._t0 = time.perf_counter() - (float(self.evals[-1]["wall_s"]) if self.evals else 0.0)
        self._plotted = -float("inf")  # when the plot was last drawn (perf_counter)
        self._drawn: tuple[int, int] | None = None  # the rows it was drawn from
        self.after_eval = _AfterEval(self)

    def _on_step(self) -> bool:
        for info in self.locals.get("infos", ()):
            episode = info.get("episode")
            if episode is not None:
                success = info.get("is_success")
                self.episodes.append(
                    {
                        "timesteps": self.num_timesteps,
                        "return": float(episode["r"]),
                        "length": int(episode["l"]),
                        "is_success": "" if success is None else int(bool(success)),
                    }
                )
        return True

    def record_eval(self, parent: EvalCallback) -> None:
        returns = np.asarray(parent.evaluations_results[-1], dtype=float)
        lengths = np.asarray(parent.evaluations_length[-1], dtype=float)
        successes = parent._is_success_buffer  # SB3 fills it from info["is_success"]
        self.evals.append(
            {
                "timesteps": parent.num_timesteps,
                "mean_return": float(returns.mean()),
                "std_return": float(returns.std()),
                "success_rate": float(np.mean(successes)) if successes else "",
                "mean_length": float(lengths.mean()),
                "wall_s": round(time.perf_counter() - self._t0, 2),
            }
        )
        self.flush(plot=time.perf_counter() - self._plotted >= PLOT_SECONDS)

    def flush(self, plot: bool = True) -> None:
        """Write episodes.csv, eval.csv and (with `plot`, where rows came since it was last
        drawn) learning_curve.png, each atomically."""
        write_rows(self.episodes_csv, EPISODE_FIELDS, self.episodes)
        write_rows(self.eval_csv, EVAL_FIELDS, self.evals)
        rows = (len(self.episodes), len(self.evals))
        if plot and rows != self._drawn:
            plot_curves(self.episodes, self.evals, self.plot_png, self.title)
            self._plotted, self._drawn = time.perf_counter(), rows

    def truncate(self, up_to_timesteps: int) -> None:
        """Drop the rows recorded after `up_to_timesteps` (a run stopped mid-rollout keeps
        the count its weights have learnt from; the resumed run records them again)."""
        self.episodes = [r for r in self.episodes if int(r["timesteps"]) <= up_to_timesteps]
        self.evals = [r for r in self.evals if int(r["timesteps"]) <= up_to_timesteps]

    def close(self) -> None:
        """Flush, and remove the staging directory if the evaluations left it empty."""
        self.flush()
        if self.staging_dir.exists() and not any(self.staging_dir.iterdir()):
            self.staging_dir.rmdir()


class _AfterEval(BaseCallback):
    def __init__(self, owner: CurveLogger):
        super().__init__()
        self.owner = owner

    def _on_step(self) -> bool:
        self.owner.record_eval(self.parent)
        staged = Path(self.parent.log_path + ".npz") if self.parent.log_path else None
        if staged is not None and staged.exists():  # SB3 wrote it in place; publish atomically
            os.replace(staged, self.owner.run_dir / "evaluations.npz")
        return True


def plot_curves(episodes: list[dict], evals: list[dict], path: Path, title: str) -> None:
    """Training returns (per episode and a moving mean) and evaluation mean +- sd (the
    spread of the evaluation episodes' returns), every element in the legend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    if episodes:
        t = np.array([int(r["timesteps"]) for r in episodes])
        r = np.array([float(r["return"]) for r in episodes])
        ax.plot(t, r, ".", ms=2, alpha=0.3, color="tab:blue", label="training episode")
        k = max(1, min(20, len(r) // 5))
        mean = np.convolve(r, np.ones(k) / k, "valid")
        ax.plot(t[k - 1 :], mean, color="tab:blue", label=f"training, mean of {k} episodes")
    if evals:
        t = np.array([int(r["timesteps"]) for r in evals])
        m = np.array([float(r["mean_return"]) for r in evals])
        s = np.array([float(r["std_return"]) for r in evals])
        ax.plot(t, m, "o-", color="tab:orange", label="evaluation (deterministic)")
        band = "evaluation mean +- sd"
        ax.fill_between(t, m - s, m + s, color="tab:orange", alpha=0.2, label=band)
    ax.set(xlabel="environment steps", ylabel="episode return", title=title)
    ax.grid(alpha=0.3)
    if episodes or evals:
        ax.legend(loc="lower right")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)
