"""How learning failed. The probe of the task's success set (`success_edges`,
`flat_components`) is the learning wing's (`agents.learning.flat`), read here.

`diagnose(env_id, agent, episodes, seed)` runs the agent from the evaluation's starts and
says where its episodes ended: how each ended, the distance of the last state to the
operating point in units of the success edges (the components outside the set), whether
the agent held still just outside (the last fifth of the episode moved less than a tenth
of an edge while 1-3 edges out), beside LQR (or the plan) from the same starts.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import gymnasium as gym
import numpy as np

from dynamics import wrap

from ..common import lagrange_env, spec
from ..learning.flat import Edges, flat_components, success_edges


# ---- where a failed agent's episodes end ---------------------------------------------------
@dataclass(frozen=True)
class Ends:
    """The last states of an agent's episodes and how they ended."""

    agent: str
    endings: dict  # ending -> episodes (agents.scoring.episodes.ENDINGS)
    distance: np.ndarray  # (episodes,) max over components of |x_T - x0| / edge
    outside: dict  # component -> episodes that ended outside the set along it
    still_outside: int  # episodes that held still 1-3 edges out for the last fifth
    lqr_share: float | None  # share of steps LQR acted (hand-over agents), else None
    within: dict = dataclasses.field(default_factory=dict)  # component -> share inside its edge


def rollout_ends(
    make_agent, env_id: str, agent, episodes: int, seed: int, edges: Edges, name: str
) -> Ends:
    """Run `agent` (a name or a path, built by `make_agent(name, venv, seed)`, as
    agents.evaluate's) from seeds seed.. and collect where its episodes end, in units of
    the success edges."""
    from .episodes import EvalStats

    venv = gym.make_vec(spec(env_id), num_envs=episodes, vectorization_mode="vector_entry_point")
    try:
        policy = make_agent(agent, venv, seed) if isinstance(agent, str) else agent
        base = lagrange_env(venv)
        obs, _ = venv.reset(seed=seed)
        x0, _ = base.operating_point(obs)
        running = np.ones(episodes, dtype=bool)
        trail, last = [], np.zeros((episodes, len(edges.names)))
        success, early, diverged = (np.zeros(episodes, dtype=bool) for _ in range(3))
        returns, lengths = np.zeros(episodes), np.zeros(episodes, dtype=np.int64)
        while running.any():
            action, _ = policy.predict(obs, deterministic=True)
            obs, reward, terminated, truncated, info = venv.step(action)
            x = base.state_from_observation(obs)
            trail.append(np.where(running[:, None], x, np.nan))
            returns[running] += reward[running]
            lengths[running] += 1
            done = running & (terminated | truncated)
            last[done] = x[done]
            success[done] = np.asarray(info["is_success"])[done]
            early[done] = np.asarray(terminated)[done]
            diverged[done] = np.asarray(info.get("diverged", np.zeros(episodes, bool)))[done]
            running &= ~done
    finally:
        venv.close()
    stats = EvalStats(returns, lengths, success, early, diverged & early)
    capture = getattr(policy, "capture", None)
    share = None
    if capture is not None and getattr(policy, "steps", 0):
        share = policy.lqr_steps / policy.steps
    dx = last - x0
    periodic = np.flatnonzero(np.asarray(base.periodic, dtype=bool))
    dx[:, periodic] = wrap(dx[:, periodic])
    return _ends(name, stats, np.stack(trail, axis=1), dx, edges, share)


def _ends(name, stats, trail, dx, edges: Edges, share) -> Ends:
    scale = np.where(np.isfinite(edges.edge) & (edges.edge > 0), edges.edge, np.inf)
    err = np.abs(dx) / scale
    distance = np.nanmax(np.where(np.isfinite(err), err, 0.0), axis=1)
    outside = {n: int((err[:, i] > 1).sum()) for i, n in enumerate(edges.names)}
    # the success set's conditions, one per component it bounds (a finite edge): the
    # share of episodes whose last state lies within the edge along it
    within = {
        n: float(np.mean(err[:, i] <= 1))
        for i, n in enumerate(edges.names)
        if np.isfinite(scale[i]) and len(err)
    }
    tail = trail[:, -max(trail.shape[1] // 5, 2) :]
    path = np.nansum(np.abs(np.diff(tail, axis=1)), axis=1)  # per component, last fifth
    moved = np.max(np.where(np.isfinite(scale), path / scale, 0.0), axis=1)
    ended_late = ~np.asarray(stats.terminated, bool) & ~np.asarray(stats.successes, bool)
    still = int((ended_late & (moved < 0.1) & (distance > 1) & (distance <= 3)).sum())
    return Ends(
        name,
        stats.endings(),
        distance,
        {k: v for k, v in outside.items() if v},
        still,
        share,
        within,
    )


def describe_ends(ends: Ends) -> str:
    """One line: how the episodes ended and where."""
    parts = [", ".join(f"{n} {k}" for k, n in ends.endings.items() if n)]
    if len(ends.distance):
        parts.append(
            f"last state {np.median(ends.distance):.2g} success edges from the "
            "operating point (median; < 1 is inside along every component)"
        )
    if ends.within:
        parts.append(
            "at the last step within the success edge along "
            + ", ".join(f"{k} in {v:.0%}" for k, v in ends.within.items())
            + " of the episodes"
        )
    if ends.outside:
        parts.append("outside along " + ", ".join(f"{k} ({v})" for k, v in ends.outside.items()))
    if ends.still_outside:
        parts.append(f"{ends.still_outside} held still 1-3 edges outside")
    if ends.lqr_share is not None:
        parts.append(f"LQR acted in {ends.lqr_share:.0%} of the steps")
    return f"{ends.agent}: " + "; ".join(parts)


def diagnose(
    make_agent,
    env_id: str,
    agent,
    episodes: int = 20,
    seed: int = 0,
    compare: tuple[str, ...] = ("lqr",),
    name: str = "trained",
) -> list[str]:
    """Lines saying where `agent`'s episodes ended, beside the agents in `compare` (LQR,
    the plan) from the same starts; an agent that cannot run here (LQR on a time-varying
    system) is left out with its reason. make_agent: agents.evaluate.make_agent."""
    edges = success_edges(env_id, seed)
    run = lambda a, label: rollout_ends(make_agent, env_id, a, episodes, seed, edges, label)  # noqa: E731
    ends = run(agent, name)
    lines, others = [describe_ends(ends)], {}
    for other in compare:
        try:
            others[other] = run(other, other)
            lines.append(describe_ends(others[other]))
        except Exception as exc:  # Unsupported, a planner failing: say so
            lines.append(f"{other}: not run ({' '.join(str(exc).split())[:120]})")
    flat = flat_components(edges, rates=True)
    if flat:
        lines.append("reward flat inside the success tolerance along " + ", ".join(flat))
    return lines + [f"to try: {t}" for t in advice(ends, others, flat, edges)]


MISSED = 0.8
"""A condition is named as the one missed when fewer episodes than this end within it."""


def advice(ends: Ends, others: dict, flat: list[str], edges: Edges) -> list[str]:
    """What to try, from where the episodes ended: the conditions of the success set the
    agent misses (position or rate), whether it fails, holds still outside, or the agents
    compared (LQR) succeed from the same starts."""
    n = max(sum(ends.endings.values()), 1)
    missed = [k for k, v in ends.within.items() if v < MISSED]
    rates = [k for k in missed if k.endswith("_dot")]
    positions = [k for k in missed if not k.endswith("_dot")]
    out = []
    if ends.endings.get("failure", 0) + ends.endings.get("diverged", 0) > n / 2:
        out.append(
            "most episodes end early (failure or divergence): a longer budget "
            "(--budget 20m), or starts nearer the goal while it learns"
        )
    if rates and not positions:
        out.append(
            f"the agent reaches the goal but does not come to rest ({', '.join(rates)} "
            "outside the tolerance): a reward term on those rates that costs a "
            "visible share of a step's range at the tolerance, e.g. -w (rate / "
            "tolerance)^2 with w a tenth of the range; a longer budget"
        )
    elif positions:
        near = [k for k in positions if k in flat]
        what = (
            f"the reward is flat there along {', '.join(near)}: a term that grows "
            "towards the goal at the scale of the success edge (e.g. -|error| / edge)"
            if near
            else "a longer budget (--budget 20m), or another learner (--algo sac, tqc or crossq)"
        )
        out.append(
            f"the agent ends outside the set along {', '.join(positions)}"
            + (f" ({ends.still_outside} held still just outside)" if ends.still_outside else "")
            + f": {what}"
        )
    good = [a for a, e in others.items() if e.endings.get("success", 0) >= MISSED * n]
    if ends.lqr_share is not None:  # it hands over already: the successes are LQR's too
        if ends.endings.get("success", 0) >= MISSED * n:
            out.append(
                f"the successes are the hand-over's as much as the agent's (LQR acted in "
                f"{ends.lqr_share:.0%} of the steps), and the agent alone misses: a longer "
                "budget for the agent, or judge the task by the pair, as the report does"
            )
    elif good:
        out.append(
            f"{good[0]} succeeds from the same starts: where the agent brings the "
            "state near the goal, a declared LQR hand-over (hyperparams "
            "{ppo: {handover: ...}}, agents.control.handover) finishes the job"
        )
    return out
