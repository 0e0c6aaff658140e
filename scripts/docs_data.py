"""The benchmarks' data files under docs/data/ and what the site says of their age.

Every measured figure on the site comes from one dated file here (its runs name the date,
the commit, the machine and the command); a page renders it and says when the code it
describes (envs/, dynamics/, agents/) changed after the measurement.

    python scripts/docs_data.py learning runs/learning/results.csv [--command "..."]

stores a learning benchmark's results.csv (`benchmarks/learning.py`) as
docs/data/learning.json with today's date, the checkout's commit and the machine, which
the learning page then renders: a new result lands without editing prose.

    python scripts/docs_data.py main-job runs/check/results.csv --wall 1779 --command "..."

stores a run of the main job (`python -m agents.check`, its report's results.csv and its
wall time) as docs/data/main-job.json, which the home page renders.
"""

from __future__ import annotations

import argparse
import datetime
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "docs" / "data"
LEARNING = DATA / "learning.json"
MAIN_JOB = DATA / "main-job.json"
CODE = ("envs", "dynamics", "agents")  # the code a measurement describes


def _git(*args: str) -> str | None:
    try:
        done = subprocess.run(
            ["git", *args], cwd=ROOT, capture_output=True, text=True, timeout=30, check=False
        )
    except (OSError, subprocess.TimeoutExpired):
        return None
    return done.stdout.strip() if done.returncode == 0 and done.stdout.strip() else None


def head_commit() -> str | None:
    return _git("rev-parse", "HEAD")


def code_change() -> tuple[str, str] | None:
    """(commit, ISO date) of the last commit that touched envs/, dynamics/ or agents/; None
    outside a git checkout."""
    line = _git("log", "-1", "--format=%H %cI", "--", *CODE)
    return tuple(line.split(" ", 1)) if line else None  # type: ignore[return-value]


def staleness(commit: str | None, date: str | None) -> str:
    """A one-line warning when the code changed after a measurement ('' when it did not, or
    when no git history says). With the run's commit: is the last code change among its
    ancestors; without one (older files): is it dated after the run."""
    change = code_change()
    if change is None:
        return ""
    last, when = change
    if commit:
        if _is_ancestor(last, commit):
            return ""
        measured = f"at commit {commit[:10]}"
    elif date:
        if when[:19] <= date[:19].replace(" ", "T"):
            return ""
        measured = f"on {date[:10]} (no commit recorded)"
    else:
        measured = "at an unrecorded date"
    return (
        f'!!! warning "Older than the code"\n    Measured {measured}; `envs/`, `dynamics/` '
        f"or `agents/` changed since (last at commit {last[:10]}, {when[:10]}): rerun its "
        f"command to refresh it.\n"
    )


def _is_ancestor(ancestor: str, commit: str) -> bool:
    try:
        done = subprocess.run(
            ["git", "merge-base", "--is-ancestor", ancestor, commit],
            cwd=ROOT, capture_output=True, timeout=30, check=False,
        )  # fmt: skip
    except (OSError, subprocess.TimeoutExpired):
        return False
    return done.returncode == 0


def learning_section() -> str:
    """The learning benchmark's table from docs/data/learning.json, dated, in the
    benchmark's own format (benchmarks/learning.table)."""
    refresh = (
        "```bash\npython benchmarks/learning.py --seeds 0,1,2 --out runs/learning\n"
        'python scripts/docs_data.py learning runs/learning/results.csv --command "..."\n```\n'
    )
    if not LEARNING.exists():
        return (
            "No learning results file (`docs/data/learning.json`) yet; the figures of past "
            "rounds are in the [results log](results-log.md). To measure and publish:\n\n" + refresh
        )
    data = json.loads(LEARNING.read_text(encoding="utf-8"))
    sys.path.insert(0, str(ROOT))
    from benchmarks.learning import table

    run = data["run"]
    text = table(data["rows"], float(run.get("budget_s", 600)), "").strip()
    where = f"{run['machine'].get('cores', '?')} cores, {run['machine'].get('cpu', '?')}"
    return "\n".join([
        staleness(run.get("commit"), run.get("date")),
        f"Measured {run['date'][:10]} at commit {str(run.get('commit'))[:10]} on {where}, "
        f"by `{run['command']}`.",
        "",
        text,
        "",
        "To refresh:",
        "",
        refresh,
    ])  # fmt: skip


def precision_section() -> str:
    """The precision runs (docs/data/learning-precision-*.json), newest file first, one
    table a file and one row a run: how long to the confirmed verdict, the confirmation,
    the check's 20 and fresh starts where they were scored."""
    files = sorted(DATA.glob("learning-precision-*.json"), reverse=True)
    if not files:
        return "No precision runs file (`docs/data/learning-precision-DATE.json`) yet."
    return "\n".join(_precision_table(f) for f in files)


def _precision_table(path: Path) -> str:
    data = json.loads(path.read_text(encoding="utf-8"))
    lines = [
        staleness(data.get("commit"), data.get("date")),
        f"Measured {data['date']} at commit {data.get('commit')} "
        f"({data['machine'].get('cores', '?')} cores; {data['machine'].get('note', '')}); "
        f"each row's command{' and machine' if _machines(data) else ''} in "
        f"`docs/data/{path.name}`.",
        "",
        "| system | learner | seed | variant | budget | solved after | steps | confirmed "
        "| check's 20 | fresh starts |" + (" machine |" if _machines(data) else ""),
        "|---|---|---|---|---|---|---|---|---|---|" + ("---|" if _machines(data) else ""),
    ]
    for r in data["rows"]:
        solved = r.get("solved")
        seen = (solved or {}).get("confirmed") or {}
        after = f"{solved['seconds']:.0f} s" if solved else "not solved"
        if r.get("solved_after_s") is not None:
            after = f"{r['solved_after_s']:.0f} s"
        budget = f"{r['budget_s']:.0f} s" if r.get("budget_s") else f"{r['steps_budget']:,} steps"
        conf = f"{seen['successes']} of {seen['episodes']}" if seen else ""
        check = f"{r['success_20']:.0%}" if r.get("success_20") is not None else ""
        fresh = r.get("fresh")
        fresh = f"{fresh['successes']} of {fresh['episodes']}" if fresh else ""
        lines.append(
            f"| {r['system']} | {r['learner']} | {r['seed']} | {r['variant']} | {budget} "
            f"| {after} | {r['trained_steps']:,} | {conf} | {check} | {fresh} |"
            + (f" {r.get('where', '')} |" if _machines(data) else "")
        )
    return "\n".join(lines) + "\n"


def _machines(data: dict) -> bool:
    """Whether the rows name their machines (`where`: a short label, `machine`: in full)."""
    return any("where" in r for r in data["rows"])


def store_learning(
    csvs: list[str], command: str, budget_s: float, commit: str | None = None
) -> Path:
    """docs/data/learning.json from a learning benchmark's results.csv files."""
    sys.path.insert(0, str(ROOT))
    from benchmarks.baselines import machine
    from benchmarks.learning import read_rows
    from dynamics.files import write_atomic

    data = {
        "run": {
            "command": command,
            "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
            "commit": commit or head_commit(),
            "machine": machine(),
            "budget_s": budget_s,
        },
        "rows": read_rows(csvs),
    }
    write_atomic(LEARNING, json.dumps(data, indent=1) + "\n")
    return LEARNING


def store_main_job(
    csv_path: str, wall_s: float, command: str, note: str = "", commit: str | None = None
) -> Path:
    """docs/data/main-job.json from a main job's results.csv and its wall time."""
    import csv

    sys.path.insert(0, str(ROOT))
    from benchmarks.baselines import machine
    from dynamics.files import write_atomic

    with open(csv_path, newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    data = {
        "run": {
            "command": command,
            "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
            "commit": commit or head_commit(),
            "machine": machine(),
            "wall_s": float(wall_s),
            "note": note,
        },
        "rows": rows,
    }
    write_atomic(MAIN_JOB, json.dumps(data, indent=1) + "\n")
    return MAIN_JOB


def main_job_section() -> str | None:
    """The main job's last measured run (docs/data/main-job.json): its wall time and each
    built-in's trained agent, or None where no run is stored."""
    if not MAIN_JOB.exists():
        return None
    data = json.loads(MAIN_JOB.read_text(encoding="utf-8"))
    run, m = data["run"], data["run"]["machine"]
    trained = [r for r in data["rows"] if r.get("algo") or r["agent"].endswith(" alone")]
    lines = [
        f"{run['wall_s'] / 60:.0f} minutes for the whole job on {m.get('cores', '?')} cores "
        f"({m.get('cpu', '?')}), measured {run['date'][:10]} at commit {run['commit']} by "
        f"`{run['command']}`{'; ' + run['note'] if run.get('note') else ''}. Its trained "
        "agents, each on the report's 20 episodes:",
        "",
        "| environment | agent | success [95 % CI] | trained steps | training (s) | note |",
        "|---|---|---|---|---|---|",
    ]
    for r in trained:
        steps = f"{int(float(r['timesteps'])):,}" if r.get("timesteps") else ""
        seconds = f"{float(r['train_s']):.0f}" if r.get("train_s") else ""
        lines.append(
            f"| {r['env_id']} | {r['agent']} | {float(r['success_rate']):.0%} "
            f"[{float(r['success_low']):.0%}, {float(r['success_high']):.0%}] "
            f"| {steps} | {seconds} | {r.get('note', '')} |"
        )
    old = staleness(run.get("commit"), run.get("date"))  # an admonition: its own paragraph
    return "\n".join(lines) + "\n" + (f"\n{old}\n" if old else "")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="kind", required=True)
    learning = sub.add_parser("learning", help="store a learning benchmark's results.csv")
    learning.add_argument("csv", nargs="+", help="results.csv files of benchmarks/learning.py")
    learning.add_argument("--command", default="python benchmarks/learning.py",
                          help="the benchmark's command line, as run")  # fmt: skip
    learning.add_argument("--budget", type=float, default=600.0, help="its budget, seconds")
    learning.add_argument("--commit", help="the commit it ran (default: this checkout's)")
    job = sub.add_parser("main-job", help="store a main job's results.csv and wall time")
    job.add_argument("csv", help="runs/check/results.csv of `python -m agents.check`")
    job.add_argument("--wall", type=float, required=True, help="its wall time, seconds")
    job.add_argument("--command", required=True, help="the command line, as run")
    job.add_argument("--note", default="", help="how the machine was loaded, the cache")
    job.add_argument("--commit", help="the commit it ran (default: this checkout's)")
    args = parser.parse_args(argv)
    if args.kind == "main-job":
        print(store_main_job(args.csv, args.wall, args.command, args.note, args.commit))
    else:
        print(store_learning(args.csv, args.command, args.budget, args.commit))
    return 0


if __name__ == "__main__":
    sys.exit(main())
