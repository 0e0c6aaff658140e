"""Score an agent on an environment: `python -m agents.evaluate ENV_ID --agent lqr`.

Agents: random, zero, heuristic (the environment's model-based baseline), lqr, or the
path of a trained model (model.zip or its run directory). Episodes run side by side in the
environment's native vector env (one batched step for all of them); `--video DIR` records
the first episode through Gymnasium's RecordVideo.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from pathlib import Path

import gymnasium as gym

from . import params
from .common import (
    DEFAULT_TORCH_THREADS,
    UserError,
    check_env_id,
    fail,
    lagrange_env,
    plain_warnings,
    positive_int,
    seed_int,
    spec,
    task_of,
)
from .control.policies import RandomPolicy, ZeroPolicy
from .scoring.episodes import ENDINGS, EvalStats, run_episodes, score  # noqa: F401  (ENDINGS: as before)
from .scoring.trained import SB3Policy, with_handover

BASELINES = ("random", "zero", "heuristic", "lqr", "plan")


def heuristic_of(env_id: str):
    """The task's `Heuristic` declaration for a Lagrange env id, or None."""
    try:
        return task_of(env_id).heuristic
    except UserError:
        return None


def build_heuristic(env):
    """The heuristic baseline the env's task declares, built for `env`."""
    task = lagrange_env(env).task
    if task.heuristic is None:
        raise UserError(f"Task {task.name!r} declares no heuristic baseline.")
    module, _, name = task.heuristic.target.partition(":")
    cls = getattr(importlib.import_module(module), name)
    return cls(env, **dict(task.heuristic.kwargs))


def make_agent(name: str, env, seed: int = 0):
    """A policy with SB3's predict for `env` (a Lagrange env, single or vector)."""
    space = getattr(env, "single_action_space", env.action_space)
    if name == "random":
        return RandomPolicy(space, seed)
    if name == "zero":
        return ZeroPolicy(env)
    if name == "heuristic":
        return build_heuristic(env)
    if name == "lqr":
        from .control.lqr_policy import LQRPolicy

        return LQRPolicy(env)
    if name == "plan":  # trajectory optimisation + time-varying LQR + LQR
        from .control.tvlqr import PlanPolicy

        return PlanPolicy(env)
    path = Path(name)
    if path.suffix == ".zip" or path.is_dir() or path.exists():
        return with_handover(SB3Policy.load(path, env), env)
    raise UserError(
        f"Unknown agent {name!r}: expected one of {', '.join(BASELINES)} or the path of a "
        f"trained model (model.zip or its run directory)."
    )


def evaluate(
    env_id: str,
    agent: str | object,
    episodes: int = 20,
    seed: int = 0,
    video_dir: str | Path | None = None,
    deterministic: bool = True,
    randomize: dict | None = None,
) -> EvalStats:
    """Run `episodes` episodes of `agent` (a name, a path or a policy object) from seeds
    seed, seed + 1, ...; record the first one as a video if `video_dir` is given.
    randomize: draw each episode's physical parameters (agents.learning.randomization, as training
    does); the model-based agents keep the nominal model."""
    from .learning.randomization import env_kwargs

    env_id = check_env_id(env_id)
    if episodes < 1:
        raise ValueError(f"episodes must be a positive integer, got {episodes}.")
    policies = []

    def build(venv):
        if isinstance(agent, str):
            policy = make_agent(agent, venv, seed)
        elif isinstance(agent, SB3Policy):  # acting as it was trained to, for this venv
            policy = with_handover(agent, venv)
        else:
            policy = agent
        check_policy_fits(policy, venv)
        policies.append(policy)
        return policy

    stats = score(env_id, build, episodes, seed, deterministic, **env_kwargs(env_id, randomize))
    policy = policies[0]
    if video_dir is not None:
        record_video(env_id, policy, video_dir, seed, deterministic)
    return stats


def check_policy_fits(policy, venv) -> None:
    """UserError when a trained model's spaces differ from the env's (a model trained on
    another env), before any step is taken."""
    model = getattr(policy, "model", None)
    if model is None or not hasattr(model, "observation_space"):
        return
    obs, act = venv.single_observation_space, venv.single_action_space
    if model.observation_space.shape != obs.shape or model.action_space.shape != act.shape:
        raise UserError(
            f"The model was trained on observations {model.observation_space.shape} and "
            f"actions {model.action_space.shape}; {venv.spec.id if venv.spec else 'this env'} "
            f"has {obs.shape} and {act.shape}: it was trained on another environment."
        )


def record_video(env_id: str, policy, video_dir, seed: int = 0, deterministic=True) -> Path:
    """One episode rendered to `video_dir` through Gymnasium's RecordVideo; returns it."""
    video_dir = Path(video_dir)
    env = gym.make(spec(env_id), render_mode="rgb_array")
    name = env_id.replace("/", "-")
    env = gym.wrappers.RecordVideo(env, str(video_dir), name_prefix=name, disable_logger=True)
    obs, _ = env.reset(seed=seed)
    done = False
    while not done:
        action, _ = policy.predict(obs, deterministic=deterministic)
        obs, _, terminated, truncated, _ = env.step(action)
        done = terminated or truncated
    env.close()
    return video_dir / f"{name}-episode-0.mp4"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m agents.evaluate",
        description="Mean and std of the return, success rate and episode length of an agent.",
    )
    parser.add_argument(
        "env_id", help="Gymnasium id, e.g. Lagrange/Acrobot-v2, or module:NS/Env-v0"
    )
    parser.add_argument(
        "--agent",
        required=True,
        help=f"{', '.join(BASELINES)}, or a trained model (model.zip or its run directory)",
    )
    parser.add_argument("--episodes", type=positive_int, default=20)
    parser.add_argument("--seed", type=seed_int, default=0)
    params.add_option(parser)
    parser.add_argument("--video", metavar="DIR", help="record the first episode to DIR (mp4)")
    parser.add_argument("--stochastic", action="store_true", help="sample trained policies")
    from .learning.randomization import add_option

    add_option(parser, "each episode", "; the model-based agents keep the nominal model")
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        env_id = check_env_id(args.env_id)
    except ValueError as exc:
        fail(parser, exc)
    if args.agent not in BASELINES and not Path(args.agent).exists():
        fail(
            parser,
            f"unknown agent {args.agent!r}: choose {', '.join(BASELINES)} or the path of a "
            f"trained model",
        )
    from .common import set_torch_threads

    set_torch_threads(DEFAULT_TORCH_THREADS)
    from .learning.randomization import describe, parse_option

    try:
        randomize = parse_option(args.randomize)
        with params.applied(env_id, args.params and params.load(args.params, env_id)):
            stats = evaluate(
                env_id,
                args.agent,
                args.episodes,
                args.seed,
                args.video,
                not args.stochastic,
                randomize,
            )
    except (ValueError, FileNotFoundError) as exc:
        fail(parser, exc)
    where = f" ({describe(randomize)})" if randomize else ""
    where += f" (parameters from {args.params})" if args.params else ""
    print(f"{args.agent} on {env_id}{where}: {stats.summary()}")
    if args.video:
        print(f"Video in {args.video}")
    return 0


if __name__ == "__main__":
    plain_warnings()  # a command prints messages, not source lines
    sys.exit(main())
