"""Robustness benchmark: success rate when the plant is not the controller's model.

    python benchmarks/robustness.py                 # every env, agent and quantity
    python benchmarks/robustness.py --envs Lagrange/TwoLinkArm-v1 --agents lqr,ppo-randomized \\
        --quantities inertial --episodes 100 --grid 5
    python benchmarks/robustness.py --figures docs/img/robustness   # refresh the README's figures

After the criteria of the DFKI double-pendulum benchmark's robustness scores (model
parameter inaccuracies, measurement noise, torque noise, torque response, time delay,
perturbations): one quantity at a time is moved away from the nominal plant over a grid,
and every agent runs the same seeded episodes at every point:

- each inertial parameter (kg, kg*m^2: agents.learning.randomization) over [0.75, 1.25] x nominal,
  each body the model declares as a whole (`body NAME`: its moments times one factor), and
  all of them together (`inertial`: every mass and inertia times the same factor); a point
  that gives a body an inertia no mass distribution has (or breaks a model condition) is
  skipped and listed with the reason, the other points of its grid kept;
- obs_noise: Gaussian noise on every observation feature, std 0 .. 0.1 in its units;
- action_noise: Gaussian noise on the applied input, std 0 .. 0.4 x the input's limit;
- motor_k: first-order motor response u += k (u_cmd - u), k in [0.1, 2];
- delay: 0, 1, 2 control periods of action delay;
- push: random pushes of force 0 .. 0.5 x the system's weight (sum of masses x g).

The perturbations are the env option `perturb=` (envs.perturb); an env that refuses it
has those grids skipped with a message. The controllers keep the nominal model: LQR, the plan +
TVLQR and the heuristics are designed on the env's nominal parameters while each copy steps
its own (the per-copy parameters of `randomize={}` set through reset options), as a real
controller would be. The plan tracker follows each episode by its clock here (it otherwise
tells a new episode by the model's prediction, which a plant that is not its model misses
at every step). PPO comes in two trainings: on the nominal plant, and with every inertial
parameter drawn over [0.75, 1.25] x nominal at every reset (`--randomize inertial=0.25`).
Trained models are read from `--models DIR` (DIR/ENV/nominal and DIR/ENV/randomized, run
directories of agents.train) and trained there with the task's budget when missing
(`--no-train` skips them instead).

Every argument is checked before any work (one line and exit status 2 otherwise).
Writes results.json and results.md to --out (success with Wilson 95 % intervals per env,
agent, quantity and grid point; where LQR drops below 50 %) and one figure per env to
--figures (default: --out), each file atomically. Prints the machine's load with the table.
"""

from __future__ import annotations

import datetime
import os
import platform
import sys
import time
import warnings
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

from agents.common import UserError, env_slug, lagrange_env, set_torch_threads, task_of  # noqa: E402
from agents.scoring.report import wilson_interval  # noqa: E402
from benchmarks.baselines import commit as _commit  # noqa: E402
from benchmarks.robustness_args import (  # noqa: E402
    PERTURBATIONS,
    build_parser,
    check_args,
    check_models,
    read_results,
)
from benchmarks.robustness_report import Quantity, merge, render  # noqa: E402
from envs.checks import Unsupported  # noqa: E402

RANDOMIZED = {"inertial": 0.25}
"""How `ppo-randomized` is trained (agents.learning.randomization)."""
ALL_INERTIAL = "inertial"
"""The quantity that scales every inertial parameter together (the same factor)."""


def perturb_available(env_id: str) -> str | None:
    """None when `env_id` takes `perturb=`, else why not (one line)."""
    try:
        gym.make(env_id, perturb={"obs_noise": 0.0}).close()
    except (TypeError, ValueError) as exc:
        return f"{env_id} refuses perturb=: {exc}"
    return None


def quantities(env_id: str, grid: int, wanted: list[str] | None, scales=None) -> list[Quantity]:
    """The quantities of `env_id` named in `wanted` (names, 'inertial' for every inertial
    parameter, 'perturb' for every perturbation; None: all), each over its grid: `grid`
    points, the parameters' scales of the nominal over [0.75, 1.25] unless `scales` lists
    them."""
    from agents.learning.randomization import inertial_parameters

    env = lagrange_env(gym.make(env_id))
    system, plant = env.system, env.plant
    inertial = inertial_parameters(system)
    bodies = {
        f"body {b}": [k for k in reads if k in inertial] for b, reads in system.bodies.items()
    }
    params = inertial + list(bodies) + [ALL_INERTIAL]
    names = params + list(PERTURBATIONS)
    if wanted:
        chosen = set()
        for w in wanted:
            chosen |= set({"inertial": params, "perturb": PERTURBATIONS}.get(w, [w]))
        names = [n for n in names if n in chosen]
    scales = np.linspace(0.75, 1.25, grid) if scales is None else sorted(scales)
    fractions = np.linspace(0.0, 1.0, grid)
    weight = sum(v for k, v in system.parameters.items() if system.units[k] == "kg")
    weight *= system.parameters.get("g", 9.81)
    limit = plant.max_input
    out = []
    for name in names:
        if name in inertial or name in bodies or name == ALL_INERTIAL:
            moved = inertial if name == ALL_INERTIAL else bodies.get(name, [name])
            label = {ALL_INERTIAL: "every mass and inertia"}.get(name, name)
            out.append(_scaled(system, name, f"{label} / nominal", moved, scales))
        elif name == "obs_noise":
            pts = tuple((float(f * 0.1), {name: float(f * 0.1)}) for f in fractions)
            out.append(Quantity(name, "perturb", "observation noise std", 0.0, pts))
        elif name == "action_noise":
            pts = tuple((float(f * 0.4), {name: (f * 0.4 * limit).tolist()}) for f in fractions)
            out.append(Quantity(name, "perturb", "torque noise std / limit", 0.0, pts))
        elif name == "motor_k":
            pts = tuple((k, {name: k}) for k in (0.1, 0.25, 0.5, 1.0, 1.5, 2.0))
            out.append(Quantity(name, "perturb", "motor response k", 1.0, pts))
        elif name == "delay":
            pts = tuple((float(d), {name: d}) for d in (0, 1, 2))
            out.append(Quantity(name, "perturb", "delay (control periods)", 0.0, pts))
        elif name == "push":
            pts = tuple(
                (float(f * 0.5), {name: {"force": float(f * 0.5 * weight)}}) for f in fractions
            )
            out.append(Quantity(name, "perturb", "push force / weight", 0.0, pts))
        else:
            raise SystemExit(f"unknown quantity {name!r}; known for {env_id}: {names}")
    return out


def _scaled(system, name: str, label: str, moved: list[str], scales) -> Quantity:
    """The parameters `moved` times each scale together; the points where that is no
    possible system (a body's inertia no mass distribution has, a broken condition) are
    left out of the grid and kept, with the reason, in `impossible`."""
    pts, impossible = [], []
    for s in scales:
        values = {k: float(s * system.parameters[k]) for k in moved}
        try:
            system.check_parameter_rows({k: [v] for k, v in values.items()})
        except ValueError as exc:
            why = str(exc).split(" ({")[0].removeprefix(f"{system.name}: parameters ")
            impossible.append((float(s), why))
            continue
        pts.append((float(s), values))
    return Quantity(name, "params", label, 1.0, tuple(pts), tuple(impossible))


# ---- agents ------------------------------------------------------------------------------
def agents_of(env_id: str, wanted: list[str], models: Path, train: bool, log) -> dict:
    """{agent name: a function venv -> policy} for the agents of `wanted` that `env_id`
    has (plan and heuristic where its task declares them; PPO from `models`)."""
    from agents.evaluate import make_agent
    from agents.scoring.trained import SB3Policy

    task = task_of(env_id)
    out = {}
    for name in wanted:
        if name == "plan" and "plan" not in task.hyperparams:
            continue
        if name == "heuristic" and task.heuristic is None:
            continue
        if name.startswith("ppo"):
            run = trained(env_id, name, models, train, log)
            if run is None:
                continue
            out[name] = _trained_maker(SB3Policy.load(run))
        elif name == "plan":  # one tracker for every venv: it follows episodes by its clock
            out[name] = _plan_maker()
        else:
            out[name] = lambda venv, n=name: make_agent(n, venv)
    return out


def _trained_maker(policy):
    """venv -> the trained policy acting as agents.evaluate makes it act: with its run's LQR
    hand-over and feed-forward built for that venv (agents.scoring.trained.with_handover)."""
    from agents.scoring.trained import with_handover

    return lambda venv: with_handover(policy, venv)


def _plan_maker():
    cache = {}

    def make(venv):
        if "policy" not in cache:
            from agents.control.tvlqr import PlanPolicy

            cache["policy"] = PlanPolicy(venv)
            cache["policy"].RESET_TOLERANCE = np.inf  # new episodes: episode_start only
        return cache["policy"]

    return make


def trained(env_id: str, name: str, models: Path, train: bool, log) -> Path | None:
    """The run directory of PPO `name` ('ppo': nominal; 'ppo-randomized') for `env_id`
    under `models`, trained there first (the task's budget) when missing and `train`."""
    kind = "randomized" if name == "ppo-randomized" else "nominal"
    run = models / env_slug(env_id) / kind
    if (run / "model.zip").exists():
        return run
    if not train:
        log(f"  {name}: no model in {run}; skipped (--no-train)")
        return None
    from agents.train import train as train_agent

    log(f"  {name}: training into {run} (the task's budget) ...")
    randomize = RANDOMIZED if kind == "randomized" else None
    has_checkpoint = (run / "checkpoints").is_dir()
    train_agent(env_id, run_dir=run, randomize=randomize, resume=has_checkpoint, progress=False)
    return run


# ---- episodes ----------------------------------------------------------------------------
def successes(venv, policy, seeds: list[int], options: dict | None) -> np.ndarray:
    """Success (bool per copy) of the first episode of every copy of `venv`, copy i reset
    with seeds[i]; `policy` is told the episodes' start (episode_start) on the first step."""
    n = venv.num_envs
    obs, _ = venv.reset(seed=seeds, options=options)
    done = np.zeros(n, dtype=bool)
    won = np.zeros(n, dtype=bool)
    start = np.ones(n, dtype=bool)
    while not done.all():
        action, _ = policy.predict(obs, episode_start=start, deterministic=True)
        obs, _, terminated, truncated, info = venv.step(action)
        start = np.zeros(n, dtype=bool)
        ended = ~done & (terminated | truncated)
        won[ended] = np.asarray(info["is_success"])[ended]
        done |= ended
    return won


def run_quantity(env_id, q: Quantity, makers: dict, episodes: int, seed: int) -> list[dict]:
    """Rows {agent, quantity, x, n, successes, rate, low, high} for every agent and grid
    point of `q`: every point runs the same seeds seed .. seed + episodes - 1."""
    seeds = list(range(seed, seed + episodes))
    rows = []
    if q.kind == "params":  # every point at once: one copy per (point, episode)
        venvs = [(None, _vec(env_id, episodes * len(q.points), randomize={}))]
        names = list(q.points[0][1])
        params = {k: np.repeat([s[k] for _, s in q.points], episodes) for k in names}
        options = {"params": params}
        seeds = seeds * len(q.points)
    else:
        # the nominal point is the env without the option (bit for bit the nominal plant)
        venvs = [(x, _vec(env_id, episodes, **({"perturb": s} if x != q.nominal else {})))
                 for x, s in q.points]  # fmt: skip
        options = None
    for agent, make in makers.items():
        won = []
        for _, venv in venvs:
            won.append(successes(venv, make(venv), seeds, options))
        won = np.concatenate(won).reshape(len(q.points), episodes)
        for (x, _), w in zip(q.points, won):
            interval = wilson_interval(int(w.sum()), episodes)
            rows.append(dict(agent=agent, quantity=q.name, x=x, n=episodes,
                             successes=int(w.sum()), rate=float(w.mean()),
                             low=interval.low, high=interval.high))  # fmt: skip
    for _, venv in venvs:
        venv.close()
    return rows


def _vec(env_id: str, n: int, **options):
    with warnings.catch_warnings():  # per-copy values of parameters the task's limits use
        warnings.simplefilter("ignore", RuntimeWarning)
        return gym.make_vec(env_id, n, vectorization_mode="vector_entry_point", **options)


# ---- the run -----------------------------------------------------------------------------
def bench_env(env_id, args, log) -> tuple[dict, list[Quantity]]:
    qs = quantities(env_id, args.grid, args.quantities, args.scales)
    skipped = []
    for q in qs:
        for x, why in q.impossible:
            skipped.append(f"{q.name} x {x:g} skipped, no possible plant: parameters {why}")
            log(f"  {skipped[-1]}")
    qs = [q for q in qs if q.points]
    if any(q.kind == "perturb" for q in qs):
        why = perturb_available(env_id)
        if why is not None:
            names = [q.name for q in qs if q.kind == "perturb"]
            skipped.append(f"skipped {', '.join(names)}: {why}")
            log(f"  {skipped[-1]}")
            qs = [q for q in qs if q.kind != "perturb"]
    makers = agents_of(env_id, args.agents, Path(args.models), not args.no_train, log)
    rows = []
    for q in qs:
        start = time.perf_counter()
        new = []
        for agent, make in list(makers.items()):
            try:
                new += run_quantity(env_id, q, {agent: make}, args.episodes, args.seed)
            except (ValueError, RuntimeError) as exc:  # LQR refused (Unsupported), a bad value
                why = " ".join(str(exc).split())[:240]
                if isinstance(exc, Unsupported):  # the same reason everywhere: once
                    del makers[agent]
                    skipped.append(f"{agent} refuses {env_id}: {why}")
                else:
                    skipped.append(f"{agent} on {q.name}: {why}")
                log(f"  {skipped[-1]}")
        rows += new
        log(f"  {q.name}: {len(q.points)} points in {time.perf_counter() - start:.0f} s")
    agents = [a for a in makers if any(r["agent"] == a for r in rows)]
    result = dict(
        agents=agents, skipped=skipped, rows=rows,
        quantities=[dict(name=q.name, kind=q.kind, label=q.label, nominal=q.nominal,
                         xs=[x for x, _ in q.points],
                         impossible=[x for x, _ in q.impossible]) for q in qs],
    )  # fmt: skip
    return result, qs


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; every argument is checked before work starts, and a problem ends
    the program with one line naming it (exit status 2)."""
    parser = build_parser(__doc__)
    args = parser.parse_args(argv)
    try:
        return run(args, argv)
    except UserError as exc:
        parser.exit(2, f"{parser.prog}: error: {exc}\n")


def run(args, argv) -> int:
    env_ids = check_args(args)
    set_torch_threads(1)
    out, figures = Path(args.out), Path(args.figures or args.out)
    log = lambda text: print(text, file=sys.stderr, flush=True)  # noqa: E731
    load_start = ", ".join(f"{v:.1f}" for v in os.getloadavg())
    start = time.perf_counter()
    if args.render:
        render(merge(read_results(args.render)), out, figures)
        return 0
    for env_id in env_ids:  # a model trained on another env refused before any episode
        check_models(env_id, Path(args.models), args.agents)
    results = {"envs": {}}
    for env_id in env_ids:
        log(f"{env_id}")
        results["envs"][env_id] = bench_env(env_id, args, log)[0]
    results["runs"] = [
        dict(
            command="python benchmarks/robustness.py "
            + " ".join(sys.argv[1:] if argv is None else argv),
            date=datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
            machine=f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
            commit=_commit(),
            load_start=load_start,
            load_end=", ".join(f"{v:.1f}" for v in os.getloadavg()),
            wall_s=round(time.perf_counter() - start, 1),
            models={e: _model_settings(Path(args.models), e) for e in env_ids},
        )
    ]
    render(results, out, figures)
    return 0


def _model_settings(models: Path, env_id: str) -> dict:
    """What each PPO model was trained with (from its config.yml), for the record."""
    import yaml

    out = {}
    for kind in ("nominal", "randomized"):
        config = models / env_slug(env_id) / kind / "config.yml"
        if config.exists():
            c = yaml.safe_load(config.read_text())
            out[kind] = dict(n_timesteps=c.get("n_timesteps"),
                             randomize=(c.get("hyperparams") or {}).get("randomize"))  # fmt: skip
    return out


if __name__ == "__main__":
    sys.exit(main())
