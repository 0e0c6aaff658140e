"""`python -m agents.plan ENV_ID [--plot FILE]`: plan a motion from the task's start to its
operating point, track it with time-varying LQR and LQR in the env, and show both.

Prints the plan (horizon, iterations, how close it ends) and the tracked episode (return,
success, largest distance from the plan); `--plot` writes the planned and the tracked
state components and actions against time (matplotlib, written atomically).
"""

from __future__ import annotations

import argparse
import sys

import gymnasium as gym
import numpy as np

from .common import (
    UserError,
    atomic_path,
    check_env_id,
    fail,
    positive_number,
    seed_int,
    spec,
)
from .control.ilqr import (  # noqa: F401  (the planner's names, as imported from here before)
    DEFAULTS,
    Plan,
    PlanError,
    action_matrix,
    box_qp,
    env_step,
    env_tableau,
    plan,
    plan_options,
    rollout,
    step_jacobians,
)


def run(env_id: str, seed: int = 0, horizon: float | None = None, replan: bool = False):
    """One episode of PlanPolicy from the task's start drawn with `seed`: (policy, tracker,
    states (T + 1, 2n), actions (T, n_a), return, success)."""
    from .control.tvlqr import PlanPolicy

    env = gym.make(spec(env_id))
    try:
        obs, _ = env.reset(seed=seed)
        options = {} if horizon is None else {"horizon": horizon}
        policy = PlanPolicy(env, replan=replan, **options)
        states, actions, ret, success = [env.unwrapped.state], [], 0.0, False
        done, tracker = False, None
        while not done:
            a, _ = policy.predict(obs)
            tracker = tracker or policy._trackers[0]
            obs, r, term, trunc, info = env.step(a)
            states.append(env.unwrapped.state)
            actions.append(a)
            ret += float(r)
            success, done = bool(info["is_success"]), term or trunc
        return policy, tracker, np.array(states), np.array(actions), ret, success
    finally:
        env.close()


def plot(path, env_id: str, tracker, states, actions, names) -> None:
    """The planned and the tracked motion against time, one panel per state component
    and one for the actions."""
    import matplotlib.pyplot as plt

    p = tracker.plan
    t = p.dt * np.arange(len(states))
    n = states.shape[1]
    fig, axes = plt.subplots(n + 1, 1, figsize=(8, 1.6 * (n + 1)), sharex=True)
    for i, ax in enumerate(axes[:n]):
        ax.plot(p.t, p.x[:, i], "--", color="grey", label="plan")
        tracked = states[:, i]
        if i < n // 2:  # angles: continue the plan's branch
            tracked = np.unwrap(tracked) + 2 * np.pi * np.round(
                (p.x[0, i] - tracked[0]) / (2 * np.pi)
            )
        ax.plot(t, tracked, color="C0", label="tracked")
        ax.set_ylabel(names[i], fontsize=8)
    axes[n].step(p.t[:-1], p.actions[:, 0], "--", where="post", color="grey", label="plan")
    axes[n].step(t[:-1], actions.reshape(len(actions), -1)[:, 0], where="post", color="C1")
    axes[n].set_ylabel("action 0", fontsize=8)
    axes[n].axvline(p.t[-1], color="k", lw=0.5)
    axes[n].set_xlabel("time (s); LQR from the vertical line on")
    axes[0].legend(loc="upper right", fontsize=8)
    fig.suptitle(f"{env_id}: planned (iLQR) and tracked (TVLQR, then LQR) motion")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp)
    plt.close(fig)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m agents.plan", description=__doc__)
    parser.add_argument("env_id", help="a Lagrange env id, e.g. Lagrange/Acrobot-v2")
    parser.add_argument("--seed", type=seed_int, default=0, help="start's seed")
    parser.add_argument("--horizon", type=positive_number, help="plan length, s (task's)")
    parser.add_argument("--replan", action="store_true", help="plan from the drawn start")
    parser.add_argument("--plot", metavar="FILE", help="write the motion as an image")
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        env_id = check_env_id(args.env_id, lagrange=True)
        policy, tracker, states, actions, ret, success = run(
            env_id, args.seed, args.horizon, args.replan
        )
    except (UserError, ValueError) as exc:
        fail(parser, exc)
    p = tracker.plan
    deviation = np.abs(policy.lqr.error(states[: p.steps + 1], p.x[: len(states)])).max()
    print(
        f"plan: {p.steps * p.dt:.2f} s, {p.iterations} iterations in {p.seconds:.1f} s, ends "
        f"{p.terminal_error:.2g} from the operating point (largest state component)"
    )
    print(
        f"tracked: return {ret:.1f}, success {success}, largest distance from the plan "
        f"{deviation:.3g}, {len(actions)} steps"
    )
    if args.plot:
        names = policy.env.plant.state_names
        plot(args.plot, env_id, tracker, states, actions, names)
        print(f"wrote {args.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
