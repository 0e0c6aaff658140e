"""Closing the loop: controllers redesigned on an identified model, on a plant they did not see.

    python benchmarks/identification.py                      # every case, 100 episodes
    python benchmarks/identification.py --cases Lagrange/TwoLinkArm-v1 --episodes 20

For each case a hidden plant has some parameters off nominal by a factor at which the
nominal model-based controller fails in the robustness benchmark (benchmarks/robustness.py,
the README's table of where each falls below 50 %). The plant is recorded under an exciting
input (`agents.control.recording`: 20 s at 100 Hz, sensor noise std 1e-3 rad or m and 1e-2
per s), its inertial parameters are identified from the record (`dynamics.identify`, the
model's other parameters as nominal, the noise estimated from the record, not given; each
estimate judged right, flagged as undetermined, or wrong), and the controller is designed
again on the identified model (`gym.make(env_id, **identified)`). Both designs, and a design
on the hidden plant's true parameters (the oracle: what a perfect identification would
give), then run the same seeded episodes on the hidden plant; `--records N` repeats the
record (its excitation and noise seeded afresh), identification and redesign N times, since
a design can sit on a knife's edge: the acrobot's plan + TVLQR designed for m1 = 0.75 (its
true value) fails on a plant with m1 x 0.75 in every episode, designed for 0.76 succeeds in
every one; the case here, every mass and inertia x 1.25, has an oracle that succeeds. The
actuators are the nominal env's throughout (`max_input`): where a task derives its input
limits from the parameters (the arm's holding torques), a heavier plant must not get
stronger motors.
Writes results.md and results.json to --out, atomically.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

from agents.common import check_env_id, write_atomic  # noqa: E402
from agents.control.recording import fit, record  # noqa: E402
from agents.scoring.report import wilson_interval  # noqa: E402


@dataclass(frozen=True)
class Case:
    env_id: str
    controller: str  # "lqr" or "plan"
    factors: dict  # parameter -> factor of the nominal value in the hidden plant
    why: str  # where the robustness benchmark has the nominal design fail


CASES = (
    Case("Lagrange/TwoLinkArm-v1", "lqr", {"m2": 0.25}, "LQR below 50 % at m2 x 0.25"),
    Case("Lagrange/Acrobot-v2", "plan", dict.fromkeys(("m1", "m2", "Ibar1", "Ibar2"), 1.25),
         "plan + TVLQR below 50 % with every mass and inertia x 1.25"),
    Case("examples.cart_pole:Examples/CartPole-v0", "lqr", {"m_cart": 0.1},
         "LQR 0 % at m_cart x 0.1"),
    Case("examples.furuta:Examples/Furuta-v0", "lqr", {"J": 0.1}, "LQR 0 % at J x 0.1"),
    Case("Lagrange/RollingDisk-v1", "lqr", {"I": 3.0},
         "LQR 0 % at I x 3 (a solid cylinder 0.73 m long: J = m r^2 / 2 stays, J <= 2 I)"),
)  # fmt: skip
NOISE = (1e-3, 1e-2)


def controller(kind: str, env_id: str, params: dict):
    """A policy designed on `env_id` with `params` (the designer's model and actuators)."""
    env = gym.make(env_id, **params)
    if kind == "lqr":
        from agents.control.lqr_policy import LQRPolicy

        return LQRPolicy(env)
    from agents.control.tvlqr import PlanPolicy

    policy = PlanPolicy(env)
    policy.RESET_TOLERANCE = np.inf  # the plant is not its model: new episodes by their start
    return policy


def successes(env_id: str, hidden: dict, policy, episodes: int, seed: int) -> np.ndarray:
    """Success of one seeded episode per copy of the hidden plant under `policy`."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        venv = gym.make_vec(env_id, episodes, vectorization_mode="vector_entry_point", **hidden)
    obs, _ = venv.reset(seed=list(range(seed, seed + episodes)))
    done = np.zeros(episodes, dtype=bool)
    won = np.zeros(episodes, dtype=bool)
    start = np.ones(episodes, dtype=bool)
    while not done.all():
        action, _ = policy.predict(obs, episode_start=start, deterministic=True)
        obs, _, terminated, truncated, info = venv.step(action)
        start[:] = False
        ended = ~done & (terminated | truncated)
        won[ended] = np.asarray(info["is_success"])[ended]
        done |= ended
    venv.close()
    return won


def score(kind: str, env_id: str, design: dict, plant: dict, episodes: int, seed: int) -> dict:
    """Successes of the controller designed on `design`, on `plant`, with their interval."""
    won = successes(env_id, plant, controller(kind, env_id, design), episodes, seed)
    ci = wilson_interval(int(won.sum()), episodes)
    return dict(successes=int(won.sum()), n=episodes, low=ci.low, high=ci.high)


def identified(env_id: str, plant: dict, seed: int, log) -> dict:
    """One record of `plant` (seeded excitation and noise) and its identification."""
    start = time.perf_counter()
    data = record(env_id, 20.0, plant, NOISE, seed=seed)
    record_s = time.perf_counter() - start
    start = time.perf_counter()
    result = fit(env_id, {k: data[k] for k in ("t", "q", "qd", "u")})  # noise not given
    identify_s = time.perf_counter() - start
    log(f"  record {seed}: {data['t'][-1]:.1f} s ({data['feedback']}) in {record_s:.1f} s, "
        f"identified in {identify_s:.2f} s")  # fmt: skip
    return dict(recorded_s=float(data["t"][-1]), feedback=str(data["feedback"]),
                rate=1.0 / float(data["t"][1] - data["t"][0]), identify_s=identify_s,
                parameters=result.parameters, unknown=result.unknown, std=result.std,
                unidentifiable=list(result.unidentifiable),
                undetermined=list(result.undetermined))  # fmt: skip


def verdicts(fitted: dict, truth: dict) -> dict:
    """Per unknown: 'right' (the truth within 3 standard errors, that error at most 25 % of
    the value), 'flagged' (listed as undetermined, kept at its given value) or 'wrong'."""
    out = {}
    for name in fitted["unknown"]:
        if name in fitted["undetermined"]:
            out[name] = "flagged"
            continue
        value, s = fitted["parameters"][name], fitted["std"][name]
        ok = abs(value - truth[name]) <= 3 * s and s <= 0.25 * abs(value)
        out[name] = "right" if ok else "wrong"
    return out


def run_case(case: Case, episodes: int, seed: int, records: int, log) -> dict:
    """Nominal and oracle designs once; record, identify and redesign `records` times."""
    env_id = check_env_id(case.env_id, lagrange=True)
    env = gym.make(env_id).unwrapped
    nominal = env.system.parameters
    motors = {"max_input": [float(v) for v in env.max_input]}
    hidden = {k: nominal[k] * f for k, f in case.factors.items()}
    truth = nominal | hidden
    plant = hidden | motors
    log(f"{env_id}: hidden plant {hidden}")
    row = dict(env_id=env_id, controller=case.controller, hidden=hidden, why=case.why)
    for design, params in (("nominal", {}), ("oracle", hidden)):
        row[design] = score(case.controller, env_id, params | motors, plant, episodes, seed)
        log(f"  {design} design: {row[design]['successes']}/{episodes}")
    row["identified"] = []
    for k in range(records):
        fitted = identified(env_id, plant, seed + k, log)
        fitted["errors"] = {
            name: fitted["parameters"][name] / truth[name] - 1 for name in fitted["unknown"]
            if name in truth and name not in fitted["undetermined"]
        }  # fmt: skip
        fitted["verdict"] = verdicts(fitted, truth)
        fitted["score"] = score(case.controller, env_id, fitted["parameters"] | motors, plant,
                                episodes, seed)  # fmt: skip
        log(f"    errors {', '.join(f'{a} {v:+.2%}' for a, v in fitted['errors'].items())}; "
            f"identified design {fitted['score']['successes']}/{episodes}")  # fmt: skip
        row["identified"].append(fitted)
    return row


def table(rows: list[dict]) -> str:
    lines = [
        "| env | controller | hidden plant | nominal design | identified design (each "
        "record) | oracle design | largest parameter error | right / flagged / wrong | "
        "record | identify (s) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]

    def cell(d):
        return f"{d['successes'] / d['n']:.0%} [{d['low']:.0%}, {d['high']:.0%}]"

    for r in rows:
        fits = r["identified"]
        worst = max(((k, v) for f in fits for k, v in f["errors"].items()),
                    key=lambda kv: abs(kv[1]), default=("-", 0.0))  # fmt: skip
        said = [v for f in fits for v in f["verdict"].values()]
        counts = " / ".join(str(said.count(k)) for k in ("right", "flagged", "wrong"))
        hidden = ", ".join(f"{k} = {v:.4g}" for k, v in r["hidden"].items())
        found = "; ".join(cell(f["score"]) for f in fits)
        feedback = ", ".join(sorted({f["feedback"] for f in fits}))
        seconds = f"{fits[0]['identify_s']:.2f}"  # the first in the process loads the model
        if len(fits) > 1:
            seconds += f" first, {max(f['identify_s'] for f in fits[1:]):.2f} later"
        lines.append(
            f"| {r['env_id']} | {r['controller']} | {hidden} | {cell(r['nominal'])} | "
            f"{found} | {cell(r['oracle'])} | {worst[0]} {worst[1]:+.2%} | {counts} | "
            f"{min(f['recorded_s'] for f in fits):.0f} s at {fits[0]['rate']:.0f} Hz, "
            f"{feedback} | {seconds} |"
        )
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    about = __doc__.split("\n\n")[1].replace("\n", " ")
    p = argparse.ArgumentParser(prog="python benchmarks/identification.py", description=about)
    p.add_argument("--cases", help="comma-separated env ids of CASES (default: all)")
    p.add_argument("--episodes", type=int, default=100)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--records",
        type=int,
        default=1,
        help="records (seeded excitation and noise) identified per case",
    )
    p.add_argument("--out", default="runs/identification")
    args = p.parse_args(argv)
    wanted = args.cases.split(",") if args.cases else None
    cases = [c for c in CASES if wanted is None or c.env_id in wanted
             or c.env_id.split(":")[-1] in wanted]  # fmt: skip
    if not cases or args.episodes < 1 or args.records < 1:
        raise SystemExit(f"--cases of {[c.env_id for c in CASES]}, --episodes >= 1, --records >= 1")
    log = lambda text: print(text, file=sys.stderr, flush=True)  # noqa: E731
    load = ", ".join(f"{v:.1f}" for v in os.getloadavg())
    start = time.perf_counter()
    rows = [run_case(c, args.episodes, args.seed, args.records, log) for c in cases]
    command = "python benchmarks/identification.py " + " ".join(sys.argv[1:] if argv is None
                                                                 else argv)  # fmt: skip
    when = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    note = (f"\n`{command}`, {when}, {time.perf_counter() - start:.0f} s, load average "
            f"{load} at the start, {os.cpu_count()} cores.\n")  # fmt: skip
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    text = table(rows) + note
    write_atomic(out / "results.md", text)
    write_atomic(out / "results.json", json.dumps(rows, indent=1, default=float))
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
