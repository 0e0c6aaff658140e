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
import os
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
    """--friction: all, or COORD=KIND and JOINT:RATE=KIND entries separated by commas."""
    if text in (None, "", "none"):
        return None
    if text == "all":
        return "all"
    out = {}
    for part in text.split(","):
        name, sep, kind = part.partition("=")
        if not sep or not name:
            raise UserError(
                f"--friction takes all, or COORD=KIND and JOINT:RATE=KIND entries "
                f"(e.g. elbow:theta2-theta1=viscous), got {text!r}."
            )
        joint, colon, rate = name.partition(":")
        out[joint] = (rate, kind) if colon else kind
    return out


MAX_SECONDS = 3600.0
"""Longest record `--record` makes (s): an hour of simulated excitation at an env's 20 Hz
is 72 000 steps, some minutes; a longer one is almost surely a typing error."""


def _noise(text: str | None):
    """--noise POSITIONS,RATES as two finite stds >= 0, or None when not given."""
    if text is None:
        return None
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 2 or not all(math.isfinite(v) and v >= 0 for v in values):
        raise UserError(
            f"--noise takes POSITIONS,RATES, two finite stds >= 0 (rad or m, and per second), "
            f"e.g. 1e-3,1e-2; got {text!r}."
        )
    return values


def _writable_dir(path: Path, option: str) -> None:
    """UserError unless `path` is (or can be made as) a folder this process can write."""
    if path.exists() and not path.is_dir():
        raise UserError(f"{option} {path}: a file is there; {option} takes a folder.")
    parent = path
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir() or not os.access(parent, os.W_OK | os.X_OK):
        raise UserError(f"{option} {path}: cannot write in {parent} (permission denied).")


def _record_path(path: Path) -> None:
    """UserError unless `path` can take the record file, before any work."""
    if path.is_dir():
        raise UserError(f"--record {path}: a folder is there; --record takes a file (.npz).")
    if path.suffix != ".npz":
        raise UserError(f"--record {path}: a record is an .npz file; name it {path.name}.npz.")
    _writable_dir(path.parent, "--record's folder")


def load_record(path: Path, env_id: str | None = None) -> dict:
    """The arrays of a record file (.npz, read without pickles), and, where the file says
    which env it was recorded on, that env checked against `env_id`."""
    import zipfile

    if not path.is_file():
        raise UserError(f"--data: no record at {path}" + (" (a folder)." if path.is_dir() else "."))
    what = (
        "an .npz record (a zip of the arrays t, q, [qd,] u, as --record writes and "
        "numpy.savez makes)"
    )
    try:
        loaded = np.load(path, allow_pickle=False)
    except (ValueError, OSError, EOFError, zipfile.BadZipFile):
        head = path.read_bytes()[:16]
        if head.startswith(b"PK"):
            how = "a damaged or truncated zip archive"
        elif head and all(32 <= c < 127 or c in b"\t\r\n" for c in head):
            how = f"text starting {head.decode()!r}"
        else:
            how = f"not a zip archive (it starts {head!r})"
        raise UserError(f"--data: {path} is not {what}: it is {how}.") from None
    if not isinstance(loaded, np.lib.npyio.NpzFile):
        raise UserError(f"--data: {path} is a single array (.npy); a record is {what}.")
    try:
        with loaded as f:
            data = {k: f[k] for k in f.files}
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
        raise UserError(f"--data: {path} is damaged (truncated?): {exc}") from None
    stored = str(data["env_id"]) if "env_id" in data else None
    if env_id is not None and stored is not None and stored != env_id:
        raise UserError(
            f"--data: {path} was recorded on {stored}, not {env_id}; fit it with its own env "
            "or record this one."
        )
    return data


def write_results(env_id: str, result, data: dict, out: Path) -> None:
    """identification.png, report.md, then parameters.yml in `out`, each atomically and
    only once all of them are made (a failure writes none of the three)."""
    import yaml

    params = {"env_id": env_id, "parameters": result.parameters}
    if result.friction:
        params["friction"] = result.friction
    if result.undetermined:
        params["undetermined"] = dict(result.undetermined)
    params["noise"] = result.noise
    text = yaml.safe_dump(params, sort_keys=False)
    markdown = report(env_id, result, data)
    out.mkdir(parents=True, exist_ok=True)
    figure(env_id, result, data, out / "identification.png")
    write_atomic(out / "report.md", markdown)
    write_atomic(out / "parameters.yml", text)


def report(env_id: str, result, data: dict) -> str:
    """The report's Markdown."""
    truth = {}
    if "plant_names" in data:
        truth = dict(zip(data["plant_names"].tolist(), data["plant_values"].tolist()))
    lines = [f"# Identification of {env_id}", ""]
    step = float(data["t"][1] - data["t"][0])
    lines.append(f"Record: {len(data['t'])} samples at {1 / step:.4g} Hz.")
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
        note = result.undetermined.get(name, "")
        if note:
            note = f"**not determined**: {note}"
        if not note and name in result.nonlinear:
            note = "nonlinear: refined by simulation error"
        true = f"{truth[name]:.5g}" if name in truth else ""
        lines.append(f"| {name} | {value:.6g} | {s:.2g} | {interval} | {true} | {note} |")
    if result.undetermined:
        lines += ["", "Not determined by this record (kept at their given values, not fitted):", ""]
        lines += [f"- {k}: {why}" for k, why in result.undetermined.items()]
    lines += ["", f"Noise: {result.noise}."]
    for warning in getattr(result, "warnings", ()):
        lines += ["", f"Warning: {warning}"]
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
    p.add_argument(
        "--noise",
        help="sensor noise std POSITIONS,RATES: --record adds it to the record (default 0,0); "
        "--data fits with it (default: the record's own noise key, else estimated from it)",
    )
    p.add_argument(
        "--rate",
        type=float,
        default=100.0,
        help="samples per second of --record (the env stepped at this rate; 100)",
    )
    p.add_argument(
        "--seconds", type=float, default=20.0, help=f"record length (s), at most {MAX_SECONDS:g}"
    )
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
    p.add_argument(
        "--friction",
        help="all, or COORD=KIND and JOINT:RATE=KIND entries, KIND viscous|coulomb|"
        "viscous+coulomb, RATE a combination of coordinates such as theta2-theta1",
    )
    p.add_argument("--given", nargs="*", metavar="NAME=VALUE", help="known parameter values")
    return p


def main(argv=None) -> int:
    p = build_parser()
    args = p.parse_args(argv)
    try:
        env_id = check_env_id(args.env_id, lagrange=True)
        if (args.record is None) == (args.data is None):
            raise UserError("give one of --record FILE or --data FILE.")
        noise = _noise(args.noise)
        if args.record is not None:
            from .control.recording import record

            if not 0 < args.seconds <= MAX_SECONDS:
                raise UserError(f"--seconds must be in (0, {MAX_SECONDS:g}], got {args.seconds:g}.")
            _record_path(args.record)
            plant = _assignments(args.plant, "--plant")
            if not (math.isfinite(args.rate) and 1 <= args.rate <= 10_000):
                raise UserError(f"--rate must be in [1, 10000] per second, got {args.rate:g}.")
            data = record(
                env_id,
                args.seconds,
                plant,
                noise or (0.0, 0.0),
                args.fraction,
                args.seed,
                args.feedback,
                args.candidates,
                args.rate,
            )
            with atomic_path(args.record, suffix=".npz") as tmp:
                np.savez(tmp, **data)
            how = "open loop" if str(data["feedback"]) == "none" else f"under {data['feedback']}"
            rate = 1.0 / float(data["t"][1] - data["t"][0])
            print(f"recorded {len(data['t'])} samples at {rate:.4g} Hz ({how}) to {args.record}")
            return 0
        if args.out is None:
            raise UserError("--data needs --out DIR.")
        _writable_dir(args.out, "--out")
        data = load_record(args.data, env_id)
        unknown = args.unknown.split(",") if args.unknown else None
        start = time.perf_counter()
        result = fit(
            env_id,
            data,
            unknown,
            _friction(args.friction),
            _assignments(args.given, "--given"),
            noise,
        )
        took = time.perf_counter() - start
        write_results(env_id, result, data, args.out)
        print(report(env_id, result, data))
        if result.undetermined:
            print(
                "NOT DETERMINED by this record (kept at their given values): "
                + ", ".join(result.undetermined)
            )
        print(
            f"identified in {took:.2f} s; wrote {args.out}/parameters.yml, report.md, "
            "identification.png"
        )
    except UserError as exc:
        fail(p, exc)
    except ValueError as exc:
        fail(p, exc)
    return 0


if __name__ == "__main__":
    sys.exit(main())
