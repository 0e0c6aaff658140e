"""The robustness benchmark's command line (benchmarks/robustness.py): its parser and every
argument checked before any work starts, each problem one line naming it."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from agents.common import UserError, check_env_id, env_slug, writable_folder
from benchmarks.robustness_report import AGENTS
from dynamics.checks import did_you_mean

PERTURBATIONS = ("obs_noise", "action_noise", "motor_k", "delay", "push")
GROUPS = ("inertial", "perturb")
"""Names for several quantities: every inertial parameter (and body, and all together),
every perturbation."""
SCALES = (1e-3, 1e3)
"""The range of a parameter grid's scales: a body a thousand times lighter or heavier is
far past where any controller of the nominal model holds, and 1e300 overflows."""
MAX_EPISODES = 10_000
"""Most episodes per grid point: each point of a parameter grid is a copy per episode, so
10,000 episodes x 9 points is already ~90,000 copies in one vector env."""
MAX_GRID = 101


def build_parser(doc: str) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python benchmarks/robustness.py", description=doc.split("\n\n")[2].replace("\n", " ")
    )
    p.add_argument("--envs", type=_names, help="comma-separated env ids (default: every one)")
    p.add_argument("--agents", type=_names, default=list(AGENTS), help=f"of {','.join(AGENTS)}")
    p.add_argument("--quantities", type=_names,
                   help="parameter names, obs_noise, action_noise, motor_k, delay, push; "
                   "'inertial' or 'perturb' for each group (default: all)")  # fmt: skip
    p.add_argument("--episodes", type=int, default=100,
                   help=f"seeded episodes per grid point (1..{MAX_EPISODES})")  # fmt: skip
    p.add_argument("--grid", type=int, default=5,
                   help=f"points of the parameter/noise grids (2..{MAX_GRID})")  # fmt: skip
    p.add_argument("--scales", type=_scales,
                   help="the parameters' grid as scales of the nominal, e.g. 0.25,0.5,1,2,4 "
                   "(default: --grid points over [0.75, 1.25]); points that would make a "
                   "body impossible are skipped and reported")  # fmt: skip
    p.add_argument("--seed", type=int, default=0, help="first seed (>= 0)")
    p.add_argument("--models", default="runs/robustness/models",
                   help="trained PPO: DIR/ENV/nominal and DIR/ENV/randomized")  # fmt: skip
    p.add_argument("--no-train", action="store_true", help="skip PPO models not in --models")
    p.add_argument("--out", default="runs/robustness", help="results.json and results.md")
    p.add_argument("--figures", help="directory of the figures (default: --out)")
    p.add_argument("--render", nargs="+", metavar="JSON",
                   help="run nothing: merge these results.json files (later ones win where "
                   "they overlap) and write the table and figures from them")  # fmt: skip
    return p


def _names(text: str) -> list[str]:
    return [t.strip() for t in text.split(",") if t.strip()]


def _scales(text: str) -> list[float]:
    """Comma-separated scales, each finite and within SCALES (one bad value refuses the
    option, naming it, rather than dropping it or the points beside it)."""
    values = []
    for t in _names(text):
        try:
            v = float(t)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{t!r} is not a number") from None
        if not (math.isfinite(v) and SCALES[0] <= v <= SCALES[1]):
            raise argparse.ArgumentTypeError(
                f"scale {t} must be a finite number within [{SCALES[0]:g}, {SCALES[1]:g}]"
            )
        values.append(v)
    if not values:
        raise argparse.ArgumentTypeError("give at least one scale, comma-separated")
    return sorted(set(values))


def check_args(args) -> list[str]:
    """The env ids the run covers, after checking every argument (UserError naming the
    first problem): agents, counts, seed, env ids, quantity names, output folders, the
    trained models there and the files to render."""
    unknown = [a for a in args.agents if a not in AGENTS]
    if unknown:
        raise UserError(
            f"--agents: unknown agent {unknown[0]!r}.{did_you_mean(unknown[0], AGENTS)} "
            f"Known: {', '.join(AGENTS)}."
        )
    if not 1 <= args.episodes <= MAX_EPISODES:
        raise UserError(f"--episodes must be within 1..{MAX_EPISODES}, got {args.episodes}.")
    if not 2 <= args.grid <= MAX_GRID:
        raise UserError(f"--grid must be within 2..{MAX_GRID}, got {args.grid}.")
    if args.seed < 0:
        raise UserError(f"--seed must be >= 0 (the seeds run from it), got {args.seed}.")
    writable_folder(Path(args.out), "--out")
    writable_folder(Path(args.figures or args.out), "--figures")
    if args.render:
        return []
    import envs

    env_ids = [check_env_id(e, lagrange=True) for e in args.envs or envs.ENV_IDS]
    if args.quantities:
        check_quantities(env_ids, args.quantities)
    return env_ids


def check_quantities(env_ids: list[str], wanted: list[str]) -> None:
    """UserError for a quantity that none of `env_ids` has (with the closest name)."""
    import gymnasium as gym

    from agents.common import lagrange_env
    from agents.learning.randomization import inertial_parameters

    known = {*GROUPS, *PERTURBATIONS, "inertial"}
    for env_id in env_ids:
        env = gym.make(env_id)
        system = lagrange_env(env).system
        known |= set(inertial_parameters(system)) | {f"body {b}" for b in system.bodies}
        env.close()
    for w in wanted:
        if w not in known:
            raise UserError(
                f"--quantities: {w!r} is no quantity of {', '.join(env_ids)}."
                f"{did_you_mean(w, sorted(known))} Known: {', '.join(sorted(known))}."
            )


def check_models(env_id: str, models: Path, wanted: list[str]) -> None:
    """UserError when a trained model under `models` for `env_id` was trained on another
    env (its config.yml's id, or its spaces), before any episode runs (as agents.evaluate)."""
    import gymnasium as gym

    from agents.scoring.trained import SB3Policy

    for kind, name in (("nominal", "ppo"), ("randomized", "ppo-randomized")):
        run = models / env_slug(env_id) / kind
        if name in wanted and (run / "model.zip").exists():
            env = gym.make(env_id)
            try:
                SB3Policy.load(run, env=env)
            except FileNotFoundError as exc:
                raise UserError(str(exc)) from None
            finally:
                env.close()


def read_results(paths: list[str]) -> list[dict]:
    """The results.json files to render, each checked: there, whole JSON, and written by
    this benchmark (UserError naming the file otherwise)."""
    out = []
    for p in map(Path, paths):
        if not p.is_file():
            raise UserError(f"--render: {p} is not a file.")
        try:
            data = json.loads(p.read_text())
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise UserError(f"--render: {p} is not whole JSON ({exc}); truncated?") from None
        ok = isinstance(data, dict) and isinstance(data.get("envs"), dict)
        ok = ok and all(
            isinstance(e, dict) and {"agents", "skipped", "rows", "quantities"} <= set(e)
            for e in data["envs"].values()
        )
        if not ok:
            raise UserError(
                f"--render: {p} is not a results.json of benchmarks/robustness.py (it needs "
                "'envs', each with agents, skipped, rows and quantities)."
            )
        out.append(data)
    return out


__all__ = ["build_parser", "check_args", "check_models", "read_results"]
