"""Whether a task's reward could guide learning: the probe of its success set, read by
scoring's diagnosis of an agent that misses the set.

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
Training does not print it at its start: it is a prediction made before any evidence, and
two built-in tasks it flags learn without help (the crank slider and the bicycle); the
diagnosis names the flat coordinates beside where a missing agent's episodes ended.
"""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium as gym
import numpy as np

from ..common import lagrange_env, spec, task_of
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
    from .defaults import episode_steps, reward_span

    env = gym.make(spec(env_id))
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
    return Edges(
        tuple(names),
        edge,
        drop,
        reward_span(task, env_id),
        episode_steps(env_id, task),
        bool(success[0]),
    )


def flat_components(edges: Edges, rates: bool = False) -> list[str]:
    """The coordinates (with `rates`, also the rates) along which the reward is flat inside
    the success set's tolerance (see the module docstring)."""
    limit = FLAT * edges.span
    return [
        name
        for name, e, d in zip(edges.names, edges.edge, edges.reward_drop)
        if np.isfinite(e)
        and np.isfinite(d)
        and abs(d) < limit
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
    parts = [f"{n} (edge {edges.edge[edges.names.index(n)]:.3g})" for n in flat]
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
