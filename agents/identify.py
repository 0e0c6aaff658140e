"""Identify an env's model from a recorded trajectory.

    python -m agents.identify Lagrange/TwoLinkArm-v1 --record arm.npz --plant m2=1.4 \
        --noise 1e-3,1e-2
    python -m agents.identify Lagrange/TwoLinkArm-v1 --data arm.npz --out runs/identify/arm

`--record` runs an exciting input on the env (with `--plant` parameters standing in for
the machine; `agents.control.recording`) and writes the record (t, q, qd, u) to an .npz file; a
record of a real machine has the same arrays. `--data` fits it (`dynamics.identify`) and
writes to `--out`: `parameters.yml` (every model parameter, what `gym.make(env_id,
**parameters)` takes), `report.md` (estimates with standard errors and 95 % intervals, the
base parameters, what is unidentifiable and why, the truth where the record carries it)
and `identification.png` (the fitted equations' generalised forces, measured against
predicted, and the identified model simulated from the record's first state against it).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from dynamics.files import atomic_path, write_atomic

from .common import UserError, check_env_id, fail
from .control.recording import fit, model_of


def _assignments(items, label: str) -> dict:
    """NAME=VALUE pairs; VALUE a number, or numbers separated by commas (a list)."""
    out = {}
    for item in items or []:
        name, sep, text = item.partition("=")
        try:
            values = [float(v) for v in text.split(",")]
        except ValueError:
            values = []
        if not sep or not name or not values or not all(map(math.isfinite, values)):
            raise UserError(f"{label} takes NAME=VALUE with finite numbers, got {item!r}.")
        out[name] = values[0] if len(values) == 1 else values
    return out


def _friction(text: str | None):
    if text in (None, "", "none"):
        return None
    if text == "all":
        return "all"
    out = {}
    for part in text.split(","):
        name, sep, kind = part.partition("=")
        if not sep:
            raise UserError(f"--friction takes all or COORD=KIND,..., got {text!r}.")
        out[name] = kind
    return out


def load_record(path: Path) -> dict:
    """The arrays of a record file (.npz)."""
    if not path.is_file():
        raise UserError(f"No record at {path}.")
    with np.load(path, allow_pickle=False) as f:
        return {k: f[k] for k in f.files}


def write_results(env_id: str, result, data: dict, out: Path) -> None:
    """parameters.yml, report.md and identification.png in `out`."""
    import yaml

    out.mkdir(parents=True, exist_ok=True)
    params = {"env_id": env_id, "parameters": result.parameters}
    if result.friction:
        params["friction"] = result.friction
    write_atomic(out / "parameters.yml", yaml.safe_dump(params, sort_keys=False))
    write_atomic(out / "report.md", report(env_id, result, data))
    figure(env_id, result, data, out / "identification.png")


def report(env_id: str, result, data: dict) -> str:
    """The report's Markdown."""
    truth = {}
    if "plant_names" in data:
        truth = dict(zip(data["plant_names"].tolist(), data["plant_values"].tolist()))
    lines = [f"# Identification of {env_id}", ""]
    if "noise" in data:
        noise = data["noise"].tolist()
        lines.append(f"Record: {len(data['t'])} samples, sensor noise std {noise}.")
    lines += [
        f"Condition number of the base regressor: {result.condition:.3g}; residual rms per "
        f"coordinate: {', '.join(f'{k} {v:.3g}' for k, v in result.residual_rms.items())}.",
        "",
        "| parameter | estimate | std | 95 % interval | truth | note |",
        "|---|---|---|---|---|---|",
    ]
    for name in result.unknown:
        value = result.parameters.get(name)
        if value is None:  # a friction coefficient
            coord, kind = name.split("_", 1)[1], name.split("_", 1)[0]
            value = result.friction[coord][kind]
        s = result.std.get(name, math.nan)
        interval = f"[{value - 1.96 * s:.5g}, {value + 1.96 * s:.5g}]" if s == s else ""
        note = result.unidentifiable.get(name, "")
        if not note and name in result.nonlinear:
            note = "nonlinear: refined by simulation error"
        true = f"{truth[name]:.5g}" if name in truth else ""
        lines.append(f"| {name} | {value:.6g} | {s:.2g} | {interval} | {true} | {note} |")
    lines += ["", "Base parameters (what the equations determine):", ""]
    for text, value in result.base.items():
        lines.append(f"- {text} = {value:.6g} (std {result.base_std[text]:.2g})")
    if result.violated:
        lines += ["", "The unconstrained fit was not physical; refitted with the constraints:"]
        lines += [f"- {v}" for v in result.violated]
    return "\n".join(lines) + "\n"


def figure(env_id: str, result, data: dict, path: Path) -> None:
    """Measured against predicted generalised forces, and a validation simulation."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    f = result.fitted
    n_eq = f["measured"].shape[1]
    fig, axes = plt.subplots(2, 1, figsize=(9, 6.5))
    for i in range(n_eq):
        axes[0].plot(f["time"], f["measured"][:, i], lw=1, label=f"equation {i}: measured")
        axes[0].plot(f["time"], f["predicted"][:, i], "--", lw=1, label=f"equation {i}: model")
    axes[0].set(xlabel="t (s)", ylabel="generalised force", title=f"{env_id}: fitted equations")
    axes[0].legend(fontsize=7, ncol=2)
    system = model_of(env_id).compile(**result.parameters)
    t, q = data["t"], data["q"]
    h = float(t[1] - t[0])
    k = min(len(t) - 1, int(round(5.0 / h)))
    x = np.concatenate([q[0], data["qd"][0] if "qd" in data else np.zeros_like(q[0])])
    sim = [x]
    for j in range(k):
        try:
            x = system.step(x, data["u"][j], dt=h, substeps=4)
        except ValueError:
            break
        sim.append(x)
    sim = np.array(sim)
    for i in range(q.shape[1]):
        axes[1].plot(t[: k + 1], q[: k + 1, i], lw=1, label=f"q{i} recorded")
        axes[1].plot(t[: len(sim)], sim[:, i], "--", lw=1, label=f"q{i} identified model")
    axes[1].set(xlabel="t (s)", ylabel="q", title="validation: simulated from the first state")
    axes[1].legend(fontsize=7, ncol=2)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=90)
    plt.close(fig)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m agents.identify", description=__doc__.split("\n\n")[0]
    )
    p.add_argument("env_id", help="registered env id (or module:Id)")
    p.add_argument("--record", type=Path, help="record an excitation into this .npz")
    p.add_argument("--data", type=Path, help="fit this record (.npz with t, q, [qd,] u)")
    p.add_argument("--out", type=Path, help="where --data writes its results")
    p.add_argument("--plant", nargs="*", metavar="NAME=VALUE", help="plant parameters (--record)")
    p.add_argument("--noise", default="0,0", help="sensor noise std: POSITIONS,RATES (--record)")
    p.add_argument("--seconds", type=float, default=20.0, help="record length (s)")
    p.add_argument("--fraction", type=float, default=0.5, help="excitation peak / action range")
    p.add_argument("--feedback", choices=["none", "lqr"], help="default: open loop, then LQR")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--candidates",
        type=int,
        default=1,
        help="excitations tried on the nominal model; the best conditioned is run",
    )
    p.add_argument("--unknown", help="comma-separated parameters (default: inertial)")
    p.add_argument("--friction", help="all, or COORD=viscous|coulomb|viscous+coulomb,...")
    p.add_argument("--given", nargs="*", metavar="NAME=VALUE", help="known parameter values")
    return p


def main(argv=None) -> int:
    p = build_parser()
    args = p.parse_args(argv)
    try:
        env_id = check_env_id(args.env_id, lagrange=True)
        if (args.record is None) == (args.data is None):
            raise UserError("give one of --record FILE or --data FILE.")
        if args.record is not None:
            from .control.recording import record

            noise = tuple(float(v) for v in args.noise.split(","))
            data = record(env_id, args.seconds, _assignments(args.plant, "--plant"), noise,
                          args.fraction, args.seed, args.feedback, args.candidates)  # fmt: skip
            with atomic_path(args.record, suffix=".npz") as tmp:
                np.savez(tmp, **data)
            how = "open loop" if str(data["feedback"]) == "none" else f"under {data['feedback']}"
            print(f"recorded {len(data['t'])} samples ({how}) to {args.record}")
            return 0
        if args.out is None:
            raise UserError("--data needs --out DIR.")
        data = load_record(args.data)
        unknown = args.unknown.split(",") if args.unknown else None
        start = time.perf_counter()
        result = fit(env_id, data, unknown, _friction(args.friction),
                     _assignments(args.given, "--given"))  # fmt: skip
        took = time.perf_counter() - start
        write_results(env_id, result, data, args.out)
        print(report(env_id, result, data))
        print(f"identified in {took:.2f} s; wrote {args.out}/parameters.yml, report.md, "
              "identification.png")  # fmt: skip
    except UserError as exc:
        fail(p, exc)
    except ValueError as exc:
        fail(p, exc)
    return 0


if __name__ == "__main__":
    sys.exit(main())
