"""The robustness benchmark's report (benchmarks/robustness.py): where an agent's success
falls below 50 %, the Markdown table, PPO randomised against nominal at the grid's ends, one
figure per env and one of the model-based controllers on every env; results of several runs
merged. Every file is written atomically."""

from __future__ import annotations

import io
import json
from dataclasses import dataclass
from pathlib import Path

from agents.common import env_slug, write_atomic

AGENTS = ("lqr", "plan", "heuristic", "ppo", "ppo-randomized")
"""The agents the benchmark knows, in the order its reports list them."""

THRESHOLD = 0.5
MODEL_BASED = ("lqr", "plan", "heuristic")
NOTE = (
    "Success rate (the task's criterion at the last step) with Wilson 95 % intervals when one "
    "quantity at a time moves away from the nominal plant; every grid point runs the same "
    "seeded episodes. The controllers keep the nominal model: LQR, the plan + TVLQR and the "
    "heuristics are designed on the nominal parameters while the plant steps the deviated "
    "ones. ppo trained on the nominal plant; ppo-randomized with every inertial parameter "
    "(kg, kg*m^2) drawn over [0.75, 1.25] x nominal at every reset."
)


@dataclass(frozen=True)
class Quantity:
    """One quantity varied over a grid: `points` are (x, setting), x the value plotted and
    the setting a reset's params ({name: value}) or an env's perturb option."""

    name: str
    kind: str  # "params" or "perturb"
    label: str
    nominal: float
    points: tuple[tuple[float, dict], ...]
    impossible: tuple[tuple[float, str], ...] = ()  # (x, why): grid points no plant can have


def drop_points(rows: list[dict], q: Quantity, agent: str = "lqr") -> dict:
    """Where `agent`'s success falls below THRESHOLD: {'nominal': its rate at the nominal
    value (None if not on the grid), and per side of it ('below', 'above'): (the farthest
    point reached before it falls, the nearest point where it is below; None where it
    never is)}, walking out from the nominal value."""
    mine = {r["x"]: r["rate"] for r in rows if r["agent"] == agent and r["quantity"] == q.name}
    out: dict = {"nominal": mine.get(q.nominal)}
    for side, keep in (("below", lambda x: x < q.nominal), ("above", lambda x: x > q.nominal)):
        xs = sorted((x for x in mine if keep(x)), key=lambda x: abs(x - q.nominal))
        if xs:
            drop = next((x for x in xs if mine[x] < THRESHOLD), None)
            held = [x for x in xs[: xs.index(drop) if drop is not None else len(xs)]]
            out[side] = (held[-1] if held else None, drop)
    return out


def describe_drop(q: Quantity, drops: dict) -> str:
    """One phrase: where the success falls below THRESHOLD on each side of the nominal."""
    if drops["nominal"] is not None and drops["nominal"] < THRESHOLD:
        return f"below {THRESHOLD:.0%} at the nominal value already ({drops['nominal']:.0%})"
    parts = []
    for side in ("below", "above"):
        if side not in drops:
            continue
        held, drop = drops[side]
        if drop is None:
            parts.append(f"holds to {held:g}")
        else:
            parts.append(f"falls below at {drop:g}" + (f" (holds at {held:g})" if held else ""))
    return "; ".join(parts)


def markdown(results: dict) -> str:
    lines = [f"# Robustness\n\n{NOTE}\n"]
    for run in results["runs"]:
        lines.append(
            f"- `{run['command']}` ({run['date']}; {run['machine']}; load average "
            f"{run['load_start']} at the start, {run['load_end']} at the end; "
            f"{run['wall_s']:.0f} s)"
        )
    for env_id, env in results["envs"].items():
        lines.append(f"\n## {env_id}\n")
        lines += [f"- {s}" for s in env["skipped"]]
        lines.append("\n| quantity | x | " + " | ".join(env["agents"]) + " |")
        lines.append("|---|---|" + "---|" * len(env["agents"]))
        find = {(r["agent"], r["quantity"], r["x"]): r for r in env["rows"]}
        for q in env["quantities"]:
            for x in q["xs"]:
                cells = [_cell(find.get((agent, q["name"], x))) for agent in env["agents"]]
                lines.append(f"| {q['name']} | {x:g} | " + " | ".join(cells) + " |")
        lines += ends_table(env)
        drops = env.get("drops") or {}
        if drops:
            agents = [a for a in MODEL_BASED if a in drops]
            lines.append(
                f"\nWhere the success falls below {THRESHOLD:.0%} (walking out from the "
                "nominal value):\n"
            )
            lines.append("| quantity | " + " | ".join(agents) + " |")
            lines.append("|---|" + "---|" * len(agents))
            for q in env["quantities"]:
                cells = [drops[a].get(q["name"], "") for a in agents]
                lines.append(f"| {q['name']} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _cell(r: dict | None) -> str:
    return "" if r is None else f"{r['rate']:.0%} [{r['low']:.0%}, {r['high']:.0%}]"


def ends_table(env: dict) -> list[str]:
    """Markdown lines: PPO trained with randomisation against nominally trained PPO at the
    ends of each parameter grid, and whether their 95 % intervals separate."""
    if not {"ppo", "ppo-randomized"} <= set(env["agents"]):
        return []
    find = {(r["agent"], r["quantity"], r["x"]): r for r in env["rows"]}
    out = [
        "\nPPO trained with randomisation against nominally trained PPO at the grid's ends:\n",
        "| quantity | x | ppo-randomized | ppo | intervals |",
        "|---|---|---|---|---|",
    ]
    for q in env["quantities"]:
        if q["kind"] != "params":
            continue
        for x in (min(q["xs"]), max(q["xs"])):
            a, b = find.get(("ppo-randomized", q["name"], x)), find.get(("ppo", q["name"], x))
            if a is None or b is None:
                continue
            verdict = ("randomised above" if a["low"] > b["high"] else
                       "nominal above" if b["low"] > a["high"] else "overlap")  # fmt: skip
            out.append(f"| {q['name']} | {x:g} | {_cell(a)} | {_cell(b)} | {verdict} |")
    return out


def plot(env_id: str, qs: list[Quantity], rows: list[dict], agents: list[str], path: Path):
    """Success against deviation, one panel per quantity, one line per agent (95 % band)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cols = min(4, len(qs))
    nrows = -(-len(qs) // cols)
    width, height = max(6.4, 3.2 * cols), 2.6 * nrows + 0.8
    fig, axes = plt.subplots(nrows, cols, figsize=(width, height), squeeze=False)
    for ax, q in zip(axes.flat, qs):
        for agent in agents:
            mine = sorted((r for r in rows if r["agent"] == agent and r["quantity"] == q.name),
                          key=lambda r: r["x"])  # fmt: skip
            if not mine:
                continue
            x = [r["x"] for r in mine]
            (line,) = ax.plot(x, [r["rate"] for r in mine], marker="o", ms=3, label=agent)
            ax.fill_between(x, [r["low"] for r in mine], [r["high"] for r in mine],
                            color=line.get_color(), alpha=0.15, lw=0)  # fmt: skip
        ax.axvline(q.nominal, color="0.6", lw=0.8, ls=":")
        ax.axhline(THRESHOLD, color="0.8", lw=0.8)
        xs = [x for x, _ in q.points]
        if q.kind == "params" and max(xs) / min(xs) > 4:
            ax.set_xscale("log")
        ax.set_xlabel(q.label)
        ax.set_ylim(-0.03, 1.03)
    for ax in axes.flat[len(qs) :]:
        ax.axis("off")
    for ax in axes[:, 0]:
        ax.set_ylabel("success")
    handles, labels = axes.flat[0].get_legend_handles_labels()
    top = 1 - 0.6 / height
    fig.suptitle(f"{env_id}: success as one quantity deviates (controllers keep the nominal "
                 "model)", fontsize=10, y=0.995)  # fmt: skip
    fig.legend(handles, labels, loc="lower center", bbox_to_anchor=(0.5, top), ncol=len(labels),
               frameon=False, fontsize=9)  # fmt: skip
    fig.tight_layout(rect=(0, 0, 1, top))
    _save(fig, path)


def _save(fig, path: Path) -> None:
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, buf.getvalue())


def model_based_agent(env: dict) -> str | None:
    """The env's model-based controller for the summary figure: the first of LQR, plan and
    heuristic that succeeds at least THRESHOLD at the nominal plant (LQR alone cannot swing
    the acrobot up from hanging; the bicycle's LQR is refused)."""
    params = {q["name"] for q in env["quantities"] if q["kind"] == "params"}
    for agent in MODEL_BASED:
        mine = [r for r in env["rows"] if r["agent"] == agent and r["quantity"] in params]
        nominal = [r for r in mine if r["x"] == 1.0]
        if nominal and min(r["rate"] for r in nominal) >= THRESHOLD:
            return agent
    return None


def plot_model_based(results: dict, path: Path) -> bool:
    """One panel per env: its model-based controller's success against each inertial
    parameter's scale (all of them together in black); False when there is nothing to draw."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [(e, env, model_based_agent(env)) for e, env in results["envs"].items()]
    panels = [p for p in panels if p[2] is not None]
    if not panels:
        return False
    cols = min(3, len(panels))
    nrows = -(-len(panels) // cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(4.2 * cols, 3.0 * nrows), squeeze=False)
    for ax, (env_id, env, agent) in zip(axes.flat, panels):
        for q in env["quantities"]:
            if q["kind"] != "params":
                continue
            mine = sorted((r for r in env["rows"] if r["agent"] == agent
                           and r["quantity"] == q["name"]), key=lambda r: r["x"])  # fmt: skip
            together = q["name"] == "inertial"
            ax.plot([r["x"] for r in mine], [r["rate"] for r in mine], marker="o", ms=2.5,
                    lw=2 if together else 1, color="k" if together else None,
                    label="all together" if together else q["name"])  # fmt: skip
        ax.axhline(THRESHOLD, color="0.8", lw=0.8)
        ax.axvline(1.0, color="0.6", lw=0.8, ls=":")
        xs = [x for q in env["quantities"] if q["kind"] == "params" for x in q["xs"]]
        if xs and max(xs) / min(xs) > 4:
            ax.set_xscale("log")
        ax.set_title(f"{env_id.split('/')[-1]}: {agent}", fontsize=9)
        ax.set_xlabel("parameter / nominal")
        ax.set_ylim(-0.03, 1.03)
        ax.legend(fontsize=6, ncol=2, loc="lower center")
    for ax in axes.flat[len(panels) :]:
        ax.axis("off")
    for ax in axes[:, 0]:
        ax.set_ylabel("success")
    fig.suptitle("Model-based controllers (nominal model) on deviated plants", fontsize=10)
    fig.tight_layout()
    _save(fig, path)
    return True


# ---- several runs, one report ----------------------------------------------------------------
def merge(results: list[dict]) -> dict:
    """One result from several runs' results.json: per env the rows of every run (a later
    run's row wins where agent, quantity and x coincide), agents, quantities and notes."""
    out: dict = {"envs": {}, "runs": []}
    for res in results:
        out["runs"] += res.get("runs", [])
        for env_id, env in res["envs"].items():
            into = out["envs"].setdefault(
                env_id, {"agents": [], "skipped": [], "rows": [], "quantities": []}
            )
            keys = {(r["agent"], r["quantity"], r["x"]) for r in env["rows"]}
            kept = [r for r in into["rows"] if (r["agent"], r["quantity"], r["x"]) not in keys]
            into["rows"] = kept + env["rows"]
            into["skipped"] += [s for s in env["skipped"] if s not in into["skipped"]]
            have = set(into["agents"]) | set(env["agents"])
            into["agents"] = [a for a in AGENTS if a in have]
            byname = {q["name"]: q for q in into["quantities"]}
            for q in env["quantities"]:
                if q["name"] in byname:
                    byname[q["name"]]["xs"] = sorted(set(byname[q["name"]]["xs"]) | set(q["xs"]))
                else:
                    into["quantities"].append(dict(q))
    return out


def quantity_of(q: dict) -> Quantity:
    return Quantity(q["name"], q["kind"], q["label"], q["nominal"], tuple((x, {}) for x in q["xs"]))


def render(results: dict, out: Path, figures: Path) -> None:
    """Where the model-based agents fall below THRESHOLD; results.json and results.md in
    `out`; one figure per env and model-based.png in `figures`; the table printed."""
    for env_id, env in results["envs"].items():
        qs = [quantity_of(q) for q in env["quantities"]]
        env["drops"] = {
            agent: {q.name: describe_drop(q, drop_points(env["rows"], q, agent)) for q in qs}
            for agent in MODEL_BASED
            if agent in env["agents"]
        }
        if env["rows"]:
            plot(env_id, qs, env["rows"], env["agents"], figures / f"{env_slug(env_id)}.png")
    plot_model_based(results, figures / "model-based.png")
    write_atomic(out / "results.json", json.dumps(results, indent=1) + "\n")
    text = markdown(results)
    write_atomic(out / "results.md", text)
    print(text)
