"""`python -m agents.lqr ENV_ID`: an LQR design printed (A, B, eigenvalues, controllability,
gain), scored in closed loop against zero torque, and its response plotted."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np

from . import params
from .common import (
    UserError,
    atomic_path,
    check_env_id,
    fail,
    positive_int,
    seed_int,
    spec,
)
from .control.linear import UncontrollableError
from .control.lqr_policy import (  # noqa: F401  (the library's names, as imported from here before)
    LQRDesign,
    LQRPolicy,
    bryson_weights,
    design,
    dlqr,
    linearize,
    start_region,
)
from .control.policies import ZeroPolicy
from .scoring.closed_loop import evaluate_near, expected_region, largest_region, perturbed_starts


def save_figure(fig, path: str) -> None:
    """fig.savefig to `path` atomically (temporary file in the same directory + replace)."""
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120)


def describe(d: LQRDesign) -> str:
    """A, B, eigenvalues, controllability and gain of a design, as text."""
    lin = d.linear

    def mat(M, rows, cols):
        head = " " * 12 + "".join(f"{c:>12.11}" for c in cols)
        body = [f"{r:>12.11}" + "".join(f"{v:12.4g}" for v in row) for r, row in zip(rows, M)]
        return "\n".join([head, *body])

    def ev(z) -> str:
        return "  ".join(f"{v:.4g}" for v in sorted(z, key=lambda v: (v.real, v.imag)))

    c = d.controllability
    return "\n".join(
        [
            f"operating point x0 = {np.array2string(lin.x0, precision=4)}, "
            f"u0 = {np.array2string(lin.u0, precision=4)}",
            "A (continuous, on the regulated state):",
            mat(lin.A, lin.states, lin.states),
            "B (per unit of normalised action):",
            mat(lin.B, lin.states, lin.inputs),
            f"open-loop eigenvalues (1/s): {ev(d.open_loop_eigenvalues)}",
            f"controllability: rank {c.rank} of {c.n}, condition number {c.condition:.3g}, "
            f"PBH margin {c.margin:.3g}",
            f"discretised with a zero-order hold at dt = {d.dt:g} s; Q diag = "
            f"{np.array2string(np.diag(d.Q), precision=4)}, R diag = "
            f"{np.array2string(np.diag(d.R), precision=4)}",
            "gain K (action = a0 - K dx):",
            mat(d.K, lin.inputs, lin.states),
            "closed-loop |z|: "
            + np.array2string(np.sort(np.abs(d.closed_loop_eigenvalues)), precision=4),
            f"closed-loop rates log(z)/dt (1/s): {ev(d.closed_loop_rates)}",
        ]
    )


def plot_response(env_id: str, path: str, seed: int = 0, Q=None, R=None, **env_kwargs) -> None:
    """The closed-loop response from one perturbed start (errors and actions vs time)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    env = gym.make(spec(env_id), **env_kwargs)
    try:
        base = env.unwrapped
        env.reset(seed=seed)
        goal = base.goal
        policy = LQRPolicy(env, Q=Q, R=R)
        region = expected_region(base)
        start = perturbed_starts(base, region, np.random.default_rng(seed))[0]
        obs, _ = env.reset(seed=seed, options={"state": start, "goal": goal})
        x0, u0 = base.operating_point()
        d = policy.design(x0, u0)
        errors, actions, success = [policy.error(base.state, x0)[d.linear.index]], [], []
        done = False
        while not done:
            a, _ = policy.predict(obs)
            obs, _, terminated, truncated, info = env.step(a)
            errors.append(policy.error(info["state"], x0)[d.linear.index])
            actions.append(a)
            success.append(info["is_success"])
            done = terminated or truncated
    finally:
        env.close()
    t = base.control_period * np.arange(len(errors))
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    ax1.plot(t, np.array(errors), label=list(d.linear.states))
    ax1.set_ylabel("x - x0 (SI; angles wrapped)")
    ax1.set_title(
        f"{env_id}: LQR from a perturbed start (seed {seed}); success at end: {success[-1]}"
    )
    ax1.legend(fontsize=8, ncol=3)
    ax2.step(t[1:], np.array(actions), where="pre", label=list(d.linear.inputs))
    ax2.set_ylabel("normalised action")
    ax2.set_xlabel("time (s)")
    ax2.set_ylim(-1.1, 1.1)
    ax2.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)


def _floats(text: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated numbers, got {text!r}"
        ) from None
    if not all(np.isfinite(v) and v > 0 for v in values):
        raise argparse.ArgumentTypeError(f"weights must be positive finite numbers, got {text!r}")
    return values


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m agents.lqr",
        description="LQR at an environment's operating point: prints A, B, eigenvalues, "
        "controllability and the gain, then scores the closed loop over seeded episodes "
        "started near the operating point (and zero torque for comparison).",
    )
    parser.add_argument(
        "env_id", help="a Lagrange env id, e.g. Lagrange/Acrobot-v2, or module:NS/Env-v0"
    )
    parser.add_argument("--episodes", type=positive_int, default=100, help="seeded episodes (100)")
    parser.add_argument("--seed", type=seed_int, default=0, help="first seed (0)")
    params.add_option(parser)
    parser.add_argument(
        "--plant",
        metavar="FILE.yml",
        type=Path,
        help="score the design on a plant with these parameters instead (a parameters.yml or "
        "a mapping; the rest nominal): design on --params (or the nominal model), evaluate on "
        "the machine; both with the nominal env's actuators (max_input)",
    )
    parser.add_argument("--scale", type=float, default=1.0, help="multiple of the start region")
    parser.add_argument("--plot", metavar="FILE", help="save the closed-loop response here")
    parser.add_argument(
        "--q", type=_floats, metavar="W,W,...", help="diagonal of Q over the regulated state"
    )
    parser.add_argument("--r", type=_floats, metavar="W,...", help="diagonal of R over actions")
    parser.add_argument(
        "--measure-region",
        action="store_true",
        help="also search the largest multiple of the region with >= 99%% success",
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    """Every argument checked before work starts; a problem ends in one line (exit 2), an
    uncontrollable linearisation in one line (exit 1), never a traceback."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not (np.isfinite(args.scale) and args.scale >= 0):
        parser.error(f"--scale must be a non-negative number, got {args.scale}")
    try:
        if args.plot:
            check_output_file(args.plot, "--plot")
        env_id = check_env_id(args.env_id, lagrange=True)
        plant = _plant(env_id, args.plant) if args.plant else None
        motors = _motors(env_id) if args.plant else {}  # the nominal env's, before --params
        with params.applied(env_id, args.params and params.load(args.params, env_id)):
            return run(args) if plant is None else run_on_plant(args, env_id, plant, motors)
    except UncontrollableError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    except (ValueError, OSError) as e:  # UserError, Unsupported, a declaration's problem
        fail(parser, " ".join(str(e).split()))


def check_output_file(path: str, option: str) -> None:
    """UserError unless `path` can be written: its folder exists and is writable, and it is
    not a folder itself (checked before the work, which would otherwise be lost)."""
    import os
    from pathlib import Path

    p = Path(path)
    if p.is_dir():
        raise UserError(f"{option} {p} is a folder; give a file name such as response.png.")
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise UserError(f"{option} {p}: the folder {folder} does not exist.")
    if not os.access(folder, os.W_OK):
        raise UserError(f"{option} {p}: the folder {folder} is not writable.")


def run(args) -> int:
    env_id = check_env_id(args.env_id, lagrange=True)
    env = gym.make(spec(env_id))
    env.reset(seed=args.seed)
    try:
        policy = LQRPolicy(env, Q=args.q, R=args.r)
        print(f"{env_id}: LQR at the operating point of the goal drawn with seed {args.seed}")
        print(describe(policy.design()))
    finally:
        env.close()
    base_region = expected_region(gym.make(spec(env_id)))
    region = {k: args.scale * v for k, v in base_region.items()}
    print(f"\nstarts: operating point + uniform perturbation within +- {region}")
    lqr_policy = lambda vec: LQRPolicy(vec, Q=args.q, R=args.r)  # noqa: E731
    for name, pol in (("LQR", lqr_policy), ("zero input", ZeroPolicy)):
        r = evaluate_near(env_id, pol, args.episodes, args.seed, scale=args.scale)
        print(
            f"{name:>11}: success {r.success.sum()}/{args.episodes} ({r.success_rate:.0%}), "
            f"return {r.returns.mean():.2f} (sd {r.returns.std():.2f})"
        )
    if args.measure_region:
        s, r = largest_region(env_id, lqr_policy, episodes=args.episodes, seed=args.seed)
        print(
            f"largest region with >= 99% success: {s:g} x the above "
            f"({ {k: s * v for k, v in base_region.items()} }), success {r.success_rate:.0%}"
        )
    if args.plot:
        plot_response(env_id, args.plot, args.seed, Q=args.q, R=args.r)
        print(f"saved {args.plot}")
    return 0


def _plant(env_id: str, path: Path) -> dict:
    """The plant's gym.make keyword arguments: every model parameter (nominal, then the
    file's) and the nominal env's actuator limits, so that what the design was not made on
    is the machine's and nothing else."""
    from envs.resolved import compile_system

    from .common import task_of

    given = params.load(path, env_id)
    nominal = dict(compile_system(task_of(env_id).model, {}).parameters)
    return nominal | given


def _motors(env_id: str) -> dict:
    """The nominal env's actuator limits (`max_input`) as a gym.make keyword argument."""
    env = gym.make(spec(env_id))
    try:
        limits = getattr(env.unwrapped, "max_input", None)
        return {} if limits is None else {"max_input": [float(v) for v in np.ravel(limits)]}
    finally:
        env.close()


def run_on_plant(args, env_id: str, plant: dict, motors: dict) -> int:
    """The design made on the model the command's env has (nominal, or --params), scored
    on `plant` (--plant), beside a design made on the plant itself (what a perfect model
    would give) and zero input."""
    design_params = params.current(env_id)  # what --params applied (none: nominal)
    design_env = gym.make(spec(env_id), **motors)
    design_env.reset(seed=args.seed)
    said = ", ".join(f"{k}={v:g}" for k, v in design_params.items()) or "its nominal values"
    print(f"{env_id}: LQR designed on the model with {said}; scored on the plant of {args.plant}")
    print(describe(LQRPolicy(design_env, Q=args.q, R=args.r).design()))
    designs = (
        ("LQR (this design)", lambda vec: LQRPolicy(design_env, Q=args.q, R=args.r)),
        ("LQR designed on the plant", lambda vec: LQRPolicy(vec, Q=args.q, R=args.r)),
        ("zero input", ZeroPolicy),
    )
    for name, pol in designs:
        r = evaluate_near(
            env_id, pol, args.episodes, args.seed, scale=args.scale, **plant, **motors
        )
        print(
            f"{name:>26}: success {r.success.sum()}/{args.episodes} ({r.success_rate:.0%}) "
            f"on the plant, return {r.returns.mean():.2f} (sd {r.returns.std():.2f})"
        )
    design_env.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
