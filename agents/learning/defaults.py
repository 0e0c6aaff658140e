"""Learning defaults derived from the task, not from a table keyed by env id.

What a task declares sets up its learner (`derived`):

- **discount**: gamma = 1 - dt / tau, with dt the control period and tau = `TAU_FRACTION`
  of the episode (max_episode_steps x dt): the agent looks a fifth of an episode ahead
  (an effective horizon of max_episode_steps / 5 steps), clipped to [`GAMMA_MIN`,
  `GAMMA_MAX`]. A 10 s episode at 50 ms gives 0.975; the Furuta example's 10 s at 20 ms
  gives 0.99.
- **reward scale**: the task's terms declare their bounds, so one step's reward lies in
  [sum of lows, sum of highs] (`reward_span`); the training env divides rewards by that
  span (`reward_scale`), so one step's reward lies in an interval of width 1 and one
  episode's return in an interval of width max_episode_steps, whatever units the user
  wrote the reward in. (VecNormalize's running reward normalisation stays on top, as
  before; the fixed scale makes the shaping below and the rewards commensurate.)
- **shaping**: potential-based shaping from LQR's cost-to-go about the operating point
  (`agents.learning.shaping`, Ng, Harada and Russell 1999), on wherever LQR can be designed:
  F = gamma Phi(s') - Phi(s) leaves the optimal policy unchanged and gives a reward that
  is flat near the goal a slope to follow. Where the operating point is a function of the
  state (the Segway example rides along its heading) the potential designs LQR row by row:
  PPO then steps slower (the operating point is solved for every row at every step) and
  learns more per step, so it is derived there too.
- **success bonus**: `SUCCESS_BONUS` (a tenth of one step's reward range) at every step
  whose state is in the task's success set (`shaping: {success: B}`). Unlike the potential
  it changes what is optimal, towards the set the check scores: a user's reward is often
  nearly flat there (the Segway's turn term, -0.1 psi_dot^2, prices a turn of 1 rad/s at
  0.2 % of a step's range while success asks |psi_dot| < 0.1). Of the sizes measured, a
  tenth and a half of a step's range did alike; the smaller is kept, as it moves the
  user's optimum less.
- **copies** (on-policy learners, PPO): a goal-conditioned task's policy must learn how its
  action depends on the goal, and one PPO update sees the goals of the episodes in one
  rollout, about one episode per copy at the default 256 steps a copy. So a task whose
  goal is drawn in d components (`Goal` with low < high) trains on at least
  `GOALS_PER_COMPONENT`^d copies, as many goals an update as a grid of four values per
  component (16 for d = 2, 64 for d = 3; the YAML default's 8 for d <= 1), with the
  minibatch grown alike so an update takes as many gradient steps (`rollout`). Wherever
  the task, the YAML's entry or the user's file sets n_envs, theirs stands.
- **feed-forward** (`feedforward: true`) wherever the inputs can hold every configuration
  at rest (as many motors as coordinates, no constraint, no explicit time: a multi-link
  arm, the crank): the agent's action is added to the one that holds the current
  configuration at rest (`agents.learning.feedforward`), so its action at any goal is zero.
- **actions** are already scaled to [-1, 1] from the declared input limits (the env);
  **observations** are standardised by VecNormalize's running statistics and clipped to
  the declared bounds by the env. Dividing by the declared bounds instead was not used:
  they are divergence limits (40 rad/s on the Furuta example's rates, where its motion
  stays within 1 rad/s), so that scale would squeeze the useful range to a few per cent.

The runs behind each rule: docs/learning.md ("What the learner derives from the task",
"Precision and goal-conditioned tasks").

The layers (agents.learning.hparams.load): the algorithm's YAML `default`, then these derived
values, then the task's own `hyperparams`, then the YAML's entry for the env id, then a
user's file: a task's author and the user still override every derived value.
"""

from __future__ import annotations

import functools

import gymnasium as gym

from ..common import spec

TAU_FRACTION = 0.2
"""The discount's time constant as a fraction of the episode."""
GAMMA_MIN, GAMMA_MAX = 0.95, 0.998
SHAPING_WEIGHT = 0.5
"""The LQR potential's range as a fraction of one episode's discounted return range."""
GOALS_PER_COMPONENT = 4
"""An on-policy rollout's copies: this to the power of the goal's drawn components."""
MAX_COPIES = 256
SUCCESS_BONUS = 0.1
"""The training reward's bonus per step inside the success set, as a fraction of one step's
reward range (after `reward_scale`)."""


def episode_steps(env_id: str, task) -> int:
    """The registry's time limit (the task's max_episode_steps where the registry has none)."""
    steps = gym.spec(env_id).max_episode_steps
    return int(steps if steps else task.max_episode_steps)


def discount(control_period: float, steps: int, fraction: float = TAU_FRACTION) -> float:
    """gamma = 1 - dt / tau with tau = `fraction` x the episode's duration, clipped."""
    if not (control_period > 0 and steps >= 1 and fraction > 0):
        raise ValueError(
            f"discount needs a positive control period, steps and fraction; got "
            f"{control_period}, {steps}, {fraction}."
        )
    tau = fraction * steps * control_period
    return float(min(max(1.0 - control_period / tau, GAMMA_MIN), GAMMA_MAX))


def reward_span(task, env_id: str | None = None) -> float:
    """The width of one step's reward range: the sum over terms of (high - low). Bounds
    that name a parameter or are functions of it are read from the made env (`env_id`)."""
    if all(isinstance(b, (int, float)) for t in task.terms for b in (t.low, t.high)):
        return float(sum(float(t.high) - float(t.low) for t in task.terms))
    if env_id is None:
        raise ValueError(f"Task {task.name!r} has reward bounds that name parameters.")
    return _span_of_env(env_id, task.name)


@functools.lru_cache(maxsize=64)
def _span_of_env(env_id: str, name: str) -> float:
    """The resolved bounds' span, from the made env (once per env id and task name)."""
    env = gym.make(spec(env_id))
    try:
        plant = env.unwrapped.plant
        return float((plant.term_high - plant.term_low).sum())
    finally:
        env.close()


def derived(env_id: str, task) -> dict:
    """The hyperparameters a task's declaration implies (see the module docstring), in the
    format of agents/learning/hyperparams/<algo>.yml; every algorithm reads the same ones."""
    steps = episode_steps(env_id, task)
    out = {"gamma": round(discount(task.control_period, steps), 6)}
    span = reward_span(task, env_id)
    if task.terms and span > 0:
        out["reward_scale"] = float(f"{1.0 / span:.6g}")
    out["shaping"] = {"lqr": SHAPING_WEIGHT, "success": SUCCESS_BONUS}
    if _holds_at_rest(env_id, task.name):
        out["feedforward"] = True
    return out


@functools.lru_cache(maxsize=64)
def _holds_at_rest(env_id: str, name: str) -> bool:
    """agents.learning.feedforward.holds_at_rest of the made env (once per id and task)."""
    from .feedforward import holds_at_rest

    env = gym.make(spec(env_id))
    try:
        return holds_at_rest(env.unwrapped.plant)
    finally:
        env.close()


def goal_dimensions(task) -> int:
    """The goal's components drawn at reset (a `Goal` with low == high is fixed)."""
    return sum(1 for g in task.goal if not _fixed(g))


def _fixed(goal) -> bool:
    try:
        return float(goal.low) == float(goal.high)
    except (TypeError, ValueError):  # bounds naming parameters: drawn
        return False


def rollout(task, hp: dict) -> dict:
    """n_envs (and batch_size, keeping the minibatches per epoch) for an on-policy learner
    of `task` from hp's: at least GOALS_PER_COMPONENT^d copies (at most MAX_COPIES), d =
    goal_dimensions."""
    base = int(hp.get("n_envs", 1))
    copies = max(base, min(GOALS_PER_COMPONENT ** goal_dimensions(task), MAX_COPIES))
    if copies == base:
        return {}
    out = {"n_envs": copies}
    if "batch_size" in hp:
        out["batch_size"] = int(hp["batch_size"]) * copies // base
    return out


def describe(hp: dict, lqr: bool = True) -> str:
    """One line saying what the derived settings in `hp` are; `lqr`: whether LQR can be
    designed for the env (where it cannot, the potential is named as left out)."""
    parts = [f"gamma {hp['gamma']:g}"] if "gamma" in hp else []
    if hp.get("n_envs"):
        parts.append(f"{hp['n_envs']} copies")
    if hp.get("reward_scale"):
        parts.append(f"rewards x {hp['reward_scale']:.3g} (1 / the declared per-step span)")
    shaping = hp.get("shaping") or {}
    if shaping.get("lqr") and not lqr:
        parts.append("no LQR potential (LQR refused this env)")
    elif shaping.get("lqr"):
        parts.append(f"LQR potential shaping {shaping['lqr']:g}")
    if shaping.get("success"):
        parts.append(f"success bonus {shaping['success']:g} a step")
    if not ((shaping.get("lqr") and lqr) or shaping.get("success")):
        parts.append("no shaping")
    if hp.get("feedforward"):
        parts.append("the holding input fed forward")
    return ", ".join(parts)
