"""What `agents.check` adds about a trained agent beyond its row: the agent alone where it
hands over to LQR, a diagnosis when it misses, and the run directory of a time budget.

- **The agent's success is its own.** A run that hands over to LQR (agents.control.handover) is
  also scored without the hand-over ("ALGO alone"), and the hand-over row's note gives the
  share of steps LQR acted and how many starts already lay inside LQR's set (where LQR
  alone would have done the work). The learning benchmark counts the agent alone wherever
  a start lies inside that set.
- **A diagnosis when learning fails**: below `SOLVED_RATE`, `agents.scoring.diagnosis.diagnose`
  says where the episodes ended, beside LQR (and the plan, where the task declares it)
  from the same starts.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..common import env_slug, spec
from ..learning.budget import SOLVED_RATE

CHANCE = 0.001
"""A confirmed agent scoring as few successes as the report's less often than this is
reported as beyond chance (`chance_note`)."""


def warm_evaluate(evaluate, env_id: str, agent: str, episodes: int, seed: int):
    """(stats, evaluation seconds, warm-up seconds) of `evaluate` (agents.evaluate's): one
    episode first, untimed, so that the evaluation's time excludes one-off costs (numba
    kernels compiled or loaded, LQR's linearisation, a model's loading)."""
    start = time.perf_counter()
    evaluate(env_id, agent, 1, seed)
    warm = time.perf_counter() - start
    start = time.perf_counter()
    stats = evaluate(env_id, agent, episodes, seed)
    return stats, time.perf_counter() - start, warm


def budget_run_dir(out: Path, env_id: str, algo: str, seed: int, seconds: float, tag="") -> Path:
    """The run directory of a wall-clock budget (beside the step budgets' ones)."""
    return Path(out) / "train" / env_slug(env_id) / f"{algo}_seed{seed}_{seconds:g}s{tag}"


def solved_note(run_dir: Path, limit: str | None) -> str:
    """The verdict of a run that stops when solved, read from its record (solved.json, and
    confirmations.json for the candidates fresh starts did not confirm): 'solved after S s,
    N steps, confirmed on K of M fresh starts (R %, 95 % [L, H])', or 'not solved in LIMIT'
    (its budget: '600 s', '400,000 steps') with the best candidate's confirmation; '' where
    `limit` is None (a run that trains its steps to the end). The one source of the
    verdict: the report's note and the learning benchmark read the same files."""
    import json

    if limit is None:
        return ""
    path = Path(run_dir) / "solved.json"
    if not path.exists():
        tried = Path(run_dir) / "confirmations.json"
        candidates = json.loads(tried.read_text()) if tried.exists() else []
        if not candidates:
            return f"not solved in {limit} (best evaluation kept)"
        best = max(candidates, key=lambda c: c["rate"])
        return (
            f"not solved in {limit}: {len(candidates)} candidate"
            f"{'s' if len(candidates) > 1 else ''} met the rule, "
            f"none confirmed (the best {confirmed_text(best)}; kept)"
        )
    solved = json.loads(path.read_text())
    note = f"solved after {solved['seconds']:.0f} s, {solved['timesteps']:,} steps"
    if "confirmed" in solved:
        note += f", confirmed on {confirmed_text(solved['confirmed'])}"
    return note


def verdict_notes(run_dir: Path, limit: str | None, stats) -> tuple[str, str]:
    """`solved_note` of the run and `chance_note` of its evaluation `stats` (the report's
    episodes)."""
    successes = np.asarray(stats.successes)
    return solved_note(run_dir, limit), chance_note(run_dir, int(successes.sum()), len(successes))


def chance_note(run_dir: Path, successes: int, episodes: int) -> str:
    """Where a confirmed run's agent succeeds in fewer than `SOLVED_RATE` of the report's
    `episodes`, how often an agent of the confirmed rate scores as few (scipy.stats.binom):
    a confirmation and a small evaluation are two samples of one rate, and this says whether
    they differ by chance or beyond it (under `CHANCE`: the two evaluations differ in what
    they score, worth reporting). '' otherwise."""
    import json

    from scipy.stats import binom

    path = Path(run_dir) / "solved.json"
    if not episodes or successes >= SOLVED_RATE * episodes or not path.exists():
        return ""
    record = json.loads(path.read_text()).get("confirmed")
    if not record:
        return ""
    p = float(binom.cdf(successes, episodes, record["rate"]))
    head = (
        f"{successes} of {episodes} here, below {SOLVED_RATE:.0%}: an agent of the confirmed "
        f"rate ({record['rate']:.0%}) scores as few in "
    )
    if p < CHANCE:
        return head + (
            f"under {100 * CHANCE:g} % of evaluations of {episodes}; the confirmation and "
            "these episodes disagree beyond chance: please report it"
        )
    return head + f"{100 * p:.2g} % of evaluations of {episodes}"


def confirmed_text(record: dict) -> str:
    """'K of M fresh starts (R %, 95 % [L, H])' of a confirmation record."""
    low, high = record["wilson95"]
    rate = f"{100 * record['rate']:.0f} %"
    return (
        f"{record['successes']} of {record['episodes']} fresh starts ({rate}, "
        f"95 % [{100 * low:.0f}, {100 * high:.0f}])"
    )


def resumed_note(run_dir: Path) -> str:
    """A note when the run was trained in several segments: a resumed run restarts its
    episodes and random streams at the checkpoint, so it is not the agent one uninterrupted
    run of the same seed trains (measured: 512 + 512 PPO steps on the bead differ from 1024
    by up to 0.012 in a weight), and its numbers are not repeatable as one command's."""
    import json

    from ..learning.timing import TIME_FILE

    path = Path(run_dir) / TIME_FILE
    segments = json.loads(path.read_text()).get("segments", []) if path.exists() else []
    if len(segments) < 2:
        return ""
    return f"resumed ({len(segments)} segments: not one uninterrupted run's agent)"


def alone_rows(programs, env_id, algo, model_path, episodes, seed, log):
    """(rows, note, share, inside): for a hand-over run, the agent scored alone, the note for
    the hand-over row, the share of steps LQR acted and how many starts lay inside LQR's
    set (otherwise [], "", None, 0). programs:
    agents.evaluate (its `make_agent` and `evaluate`; a library imports no program)."""
    import gymnasium as gym

    from .episodes import run_episodes
    from .report import Row
    from .trained import SB3Policy

    venv = gym.make_vec(spec(env_id), num_envs=episodes, vectorization_mode="vector_entry_point")
    try:
        policy = programs.make_agent(str(model_path), venv, seed)
        capture = getattr(policy, "capture", None)
        if capture is None:
            return [], "", None, 0
        obs, _ = venv.reset(seed=seed)
        inside = int(capture.split(obs)[3].sum())
        run_episodes(venv, policy, obs)
        share = policy.lqr_steps / max(policy.steps, 1)
    finally:
        venv.close()
    agent = SB3Policy.load(model_path)
    agent.handover = None  # its own actions everywhere (its feed-forward, if any, kept)
    alone = programs.evaluate(env_id, agent, episodes, seed)
    name = f"{algo} alone"
    log(f"  {name:>9}: {alone.summary()}")
    note = f"LQR acted in {share:.0%} of the steps; {inside} of {episodes} starts inside its set"
    row = Row(env_id, name, alone, 0.0, "the trained agent without the LQR hand-over")
    return [row], note, share, inside


def diagnosis_lines(programs, env_id, agent_path, rate, episodes, seed, plans, log) -> list[str]:
    """The diagnosis of a trained agent below `SOLVED_RATE` (else nothing); programs:
    agents.evaluate (its `make_agent`)."""
    from .diagnosis import diagnose

    if rate >= SOLVED_RATE or not np.isfinite(rate):
        return []
    compare = ("lqr", "plan") if plans else ("lqr",)
    try:
        lines = diagnose(programs.make_agent, env_id, str(agent_path), episodes, seed, compare)
    except Exception as exc:  # the diagnosis must never lose the report
        lines = [f"diagnosis not available: {' '.join(str(exc).split())[:160]}"]
    for line in lines:
        log(f"    {line}")
    return [f"{env_id}: {line}" for line in lines]
