"""What `agents.check` adds about a trained agent beyond its row: the agent alone where it
hands over to LQR, a diagnosis when it misses, and the run directory of a time budget.

- **The agent's success is its own.** A run that hands over to LQR (agents.handover) is
  also scored without the hand-over ("ALGO alone"), and the hand-over row's note gives the
  share of steps LQR acted and how many starts already lay inside LQR's set (where LQR
  alone would have done the work). The learning benchmark counts the agent alone wherever
  a start lies inside that set.
- **A diagnosis when learning fails**: below `SOLVED_RATE`, `agents.diagnosis.diagnose`
  says where the episodes ended, beside LQR (and the plan, where the task declares it)
  from the same starts.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from .budget import SOLVED_RATE
from .common import env_slug


def warm_evaluate(env_id: str, agent: str, episodes: int, seed: int):
    """(stats, evaluation seconds, warm-up seconds): one episode first, untimed, so that the
    evaluation's time excludes one-off costs (numba kernels compiled or loaded, LQR's
    linearisation, a model's loading)."""
    from .evaluate import evaluate

    start = time.perf_counter()
    evaluate(env_id, agent, 1, seed)
    warm = time.perf_counter() - start
    start = time.perf_counter()
    stats = evaluate(env_id, agent, episodes, seed)
    return stats, time.perf_counter() - start, warm


def budget_run_dir(out: Path, env_id: str, algo: str, seed: int, seconds: float, tag="") -> Path:
    """The run directory of a wall-clock budget (beside the step budgets' ones)."""
    return Path(out) / "train" / env_slug(env_id) / f"{algo}_seed{seed}_{seconds:g}s{tag}"


def solved_note(run_dir: Path, seconds: float | None) -> str:
    """'solved after S s, N steps' (or 'not solved in B s') for a time-budget run."""
    import json

    if seconds is None:
        return ""
    path = Path(run_dir) / "solved.json"
    if not path.exists():
        return f"not solved in {seconds:g} s (best evaluation kept)"
    solved = json.loads(path.read_text())
    return f"solved after {solved['seconds']:.0f} s, {solved['timesteps']:,} steps"


def alone_rows(env_id, algo, model_path, episodes, seed, log):
    """(rows, note): for a hand-over run, the agent scored alone, and the note for the
    hand-over row (the share of LQR's steps and the starts inside its set)."""
    import gymnasium as gym

    from .episodes import run_episodes
    from .evaluate import evaluate, make_agent
    from .policies import SB3Policy
    from .report import Row

    venv = gym.make_vec(env_id, num_envs=episodes, vectorization_mode="vector_entry_point")
    try:
        policy = make_agent(str(model_path), venv, seed)
        capture = getattr(policy, "capture", None)
        if capture is None:
            return [], ""
        obs, _ = venv.reset(seed=seed)
        inside = int(capture.split(obs)[3].sum())
        run_episodes(venv, policy, obs)
        share = policy.lqr_steps / max(policy.steps, 1)
    finally:
        venv.close()
    alone = evaluate(env_id, SB3Policy.load(model_path), episodes, seed)
    name = f"{algo} alone"
    log(f"  {name:>9}: {alone.summary()}")
    note = (f"LQR acted in {share:.0%} of the steps; {inside} of {episodes} starts inside "
            "its set")  # fmt: skip
    return [Row(env_id, name, alone, 0.0, "the trained agent without the LQR hand-over")], note


def diagnosis_lines(env_id, agent_path, success_rate, episodes, seed, plans, log) -> list[str]:
    """The diagnosis of a trained agent below `SOLVED_RATE` (else nothing)."""
    from .diagnosis import diagnose

    if success_rate >= SOLVED_RATE or not np.isfinite(success_rate):
        return []
    compare = ("lqr", "plan") if plans else ("lqr",)
    try:
        lines = diagnose(env_id, str(agent_path), episodes, seed, "trained", compare)
    except Exception as exc:  # the diagnosis must never lose the report
        lines = [f"diagnosis not available: {' '.join(str(exc).split())[:160]}"]
    for line in lines:
        log(f"    {line}")
    return [f"{env_id}: {line}" for line in lines]
