"""How learning failed, and whether the task's reward could have guided it.

`success_edges(env_id)` probes the task's success set along each state component from
the operating point: one env step (holding the operating input) from x0 + d e_i for d on a
geometric grid, both signs; the edge along i is the largest |d| still counted a success.
From the same probe, `flat_components` names the coordinates along which the reward is
flat inside the tolerance of the success set: one step just outside the set pays less than
`FLAT` (a thousandth) of one step's declared reward range less than a step at the operating
point. (On the examples a user wrote, the agents that settled a few hundredths outside
their success boxes did so along such coordinates: the Furuta example's theta, 0.002 of a
range of 3; the built-in tasks that learn, the arm, the acrobot and the bead, drop more
than 0.003 along each coordinate. Rates are left out: their tolerances are loose and their
terms small on every task, learnt or not.) `flat_reward_warning` turns that into a message.
Training no longer prints it at its start (until 2026-11-27 it did): it is a prediction
made before any evidence, and two built-in tasks it flags learn without help (the crank
slider, 8e-5 of a step's range along theta, PPO 98 % of 60 episodes over three seeds, and
the bicycle along its steer, 5e-4, 100 %; the learning benchmark of 2026-11-26); `diagnose`
names the flat coordinates beside where a missing agent's episodes ended, with the remedy.

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

from ..common import lagrange_env, task_of
from ..control.linear import state_names

FLAT = 1e-3
"""A coordinate is flat when one step just outside the success set loses less than this
fraction of one step's declared reward range."""
GRID = 2.0 ** np.arange(-12, 5)
"""Probe offsets, in the state's units (rad, m, per second): 2.4e-4 ... 16."""


@dataclass(frozen=True)
class Edges:
    """The success set seen along each state component from the operating point."""

    names: tuple[str, ...]
    edge: np.ndarray  # (n_x,) largest |d| still a success (inf: never left; nan: unknown)
    reward_drop: np.ndarray  # (n_x,) r(x0) - r(first d outside), per step
    span: float  # one step's reward range
    horizon: int  # steps per episode
    inside: bool  # whether the operating point itself counts as a success


def success_edges(env_id: str, seed: int = 0) -> Edges:
    """Probe the success set and the reward around the operating point (module docstring)."""
    from ..learning.defaults import episode_steps, reward_span

    env = gym.make(env_id)
    try:
        base = lagrange_env(env)
        obs, _ = env.reset(seed=seed)
        x0, u0 = (np.asarray(v, dtype=np.float64) for v in base.operating_point())
        g = base.goal_from_observation(obs[None])[0]
        names = state_names(base.system)
        n = len(names)
        offsets = np.concatenate([GRID, -GRID])
        rows = [x0] + [x0 + d * np.eye(n)[i] for i in range(n) for d in offsets]
        x = np.stack(rows)
        sim = base.simulator(len(x))
        sim.reset_rows(np.arange(len(x)), x, np.broadcast_to(g, (len(x), len(g))))
        a0 = np.clip(base.input_to_action(u0), -1.0, 1.0)
        sim.step(np.ascontiguousarray(np.broadcast_to(a0, (len(x), len(a0))), np.float64), None)
        success, reward = np.asarray(sim.success, bool).copy(), np.asarray(sim.R).copy()
    finally:
        env.close()
    task = task_of(env_id)
    edge, drop = np.full(n, np.nan), np.full(n, np.nan)
    if success[0]:
        k = len(offsets)
        for i in range(n):
            ok, r = success[1 + i * k : 1 + (i + 1) * k], reward[1 + i * k : 1 + (i + 1) * k]
            half = len(GRID)
            for sign in (slice(0, half), slice(half, k)):  # + then - offsets
                out = np.flatnonzero(~ok[sign])
                e = GRID[out[0] - 1] if len(out) and out[0] > 0 else (0.0 if len(out) else np.inf)
                edge[i] = e if np.isnan(edge[i]) else min(edge[i], e)
                if len(out):
                    d = reward[0] - r[sign][out[0]]
                    drop[i] = d if np.isnan(drop[i]) else min(drop[i], d)
    return Edges(tuple(names), edge, drop, reward_span(task, env_id),
                 episode_steps(env_id, task), bool(success[0]))  # fmt: skip


def flat_components(edges: Edges, rates: bool = False) -> list[str]:
    """The coordinates (with `rates`, also the rates) along which the reward is flat inside
    the success set's tolerance (see the module docstring)."""
    limit = FLAT * edges.span
    return [
        name
        for name, e, d in zip(edges.names, edges.edge, edges.reward_drop)
        if np.isfinite(e) and np.isfinite(d) and abs(d) < limit
        and (rates or not name.endswith("_dot"))
    ]


def flat_reward_warning(env_id: str, shaped: bool = True) -> str | None:
    """A message when the task's reward is flat inside the tolerance of its success set
    (see the module docstring), else None; never raises (a probe that cannot run says so
    nothing). shaped: whether the training adds the LQR shaping (the remedy it names)."""
    try:
        edges = success_edges(env_id)
    except Exception:  # a task whose operating point cannot be probed: nothing to say
        return None
    flat = flat_components(edges)
    if not flat:
        return None
    parts = [
        f"{n} (edge {edges.edge[edges.names.index(n)]:.3g})" for n in flat
    ]
    return (
        f"{env_id}: the reward is flat inside the tolerance of the success set along "
        f"{', '.join(parts)}: one step just outside the set pays less than {FLAT:g} of a "
        f"step's reward range ({edges.span:.3g}) less than one at the operating point, so "
        "the reward hardly tells an agent to enter the set (agents may settle just outside "
        "it); "
        + (
            "the LQR shaping of training (agents.learning.shaping) gives it a slope and its "
            "success bonus pays for being inside, or add a term that grows towards the goal."
            if shaped
            else "this training has no LQR shaping (the task's own settings leave it out): add "
            "a term that grows towards the goal, or ask for shaping ({lqr: 0.5, success: 0.1})."
        )
    )


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


def rollout_ends(make_agent, env_id: str, agent, episodes: int, seed: int, edges: Edges,
                 name: str) -> Ends:  # fmt: skip
    """Run `agent` (a name or a path, built by `make_agent(name, venv, seed)`, as
    agents.evaluate's) from seeds seed.. and collect where its episodes end, in units of
    the success edges."""
    from .episodes import EvalStats

    venv = gym.make_vec(env_id, num_envs=episodes, vectorization_mode="vector_entry_point")
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
    within = {n: float(np.mean(err[:, i] <= 1)) for i, n in enumerate(edges.names)
              if np.isfinite(scale[i]) and len(err)}  # fmt: skip
    tail = trail[:, -max(trail.shape[1] // 5, 2) :]
    path = np.nansum(np.abs(np.diff(tail, axis=1)), axis=1)  # per component, last fifth
    moved = np.max(np.where(np.isfinite(scale), path / scale, 0.0), axis=1)
    ended_late = ~np.asarray(stats.terminated, bool) & ~np.asarray(stats.successes, bool)
    still = int((ended_late & (moved < 0.1) & (distance > 1) & (distance <= 3)).sum())
    return Ends(name, stats.endings(), distance, {k: v for k, v in outside.items() if v},
                still, share, within)  # fmt: skip


def describe_ends(ends: Ends) -> str:
    """One line: how the episodes ended and where."""
    parts = [", ".join(f"{n} {k}" for k, n in ends.endings.items() if n)]
    if len(ends.distance):
        parts.append(f"last state {np.median(ends.distance):.2g} success edges from the "
                     "operating point (median; < 1 is inside along every component)")  # fmt: skip
    if ends.within:
        parts.append("at the last step within the success edge along " + ", ".join(
            f"{k} in {v:.0%}" for k, v in ends.within.items()) + " of the episodes")  # fmt: skip
    if ends.outside:
        parts.append("outside along " + ", ".join(f"{k} ({v})" for k, v in ends.outside.items()))
    if ends.still_outside:
        parts.append(f"{ends.still_outside} held still 1-3 edges outside")
    if ends.lqr_share is not None:
        parts.append(f"LQR acted in {ends.lqr_share:.0%} of the steps")
    return f"{ends.agent}: " + "; ".join(parts)


def diagnose(make_agent, env_id: str, agent, episodes: int = 20, seed: int = 0,
             compare: tuple[str, ...] = ("lqr",), name: str = "trained") -> list[str]:  # fmt: skip
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
        out.append("most episodes end early (failure or divergence): a longer budget "
                   "(--budget 20m), or starts nearer the goal while it learns")  # fmt: skip
    if rates and not positions:
        out.append(f"the agent reaches the goal but does not come to rest ({', '.join(rates)} "
                   "outside the tolerance): a reward term on those rates that costs a "
                   "visible share of a step's range at the tolerance, e.g. -w (rate / "
                   "tolerance)^2 with w a tenth of the range; a longer budget")  # fmt: skip
    elif positions:
        near = [k for k in positions if k in flat]
        what = (f"the reward is flat there along {', '.join(near)}: a term that grows "
                "towards the goal at the scale of the success edge (e.g. -|error| / edge)"
                if near else "a longer budget (--budget 20m), or another learner "
                "(--algo sac, tqc or crossq)")  # fmt: skip
        out.append(f"the agent ends outside the set along {', '.join(positions)}"
                   + (f" ({ends.still_outside} held still just outside)"
                      if ends.still_outside else "") + f": {what}")  # fmt: skip
    good = [a for a, e in others.items() if e.endings.get("success", 0) >= MISSED * n]
    if good:
        out.append(f"{good[0]} succeeds from the same starts: where the agent brings the "
                   "state near the goal, a declared LQR hand-over (hyperparams "
                   "{ppo: {handover: ...}}, agents.control.handover) finishes the job")  # fmt: skip
    return out
