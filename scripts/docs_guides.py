"""Pieces of the documentation site beyond the per-id and per-model tables (the site's
hooks, scripts/docs_site.py, load this file): the citation of the source chapter, an env's
arguments table and version notes, and the robustness page from the benchmark's results.

Everything an env page needs from the envs package is read through public names (the
registry's kwargs, `env.unwrapped`'s properties, docstrings), except the list of env
options with their meanings, read in one place: `env_options`.
"""

from __future__ import annotations

import ast
import importlib
import json
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ROBUSTNESS = ROOT / "docs" / "data" / "robustness.json"  # benchmarks/robustness.py's results
ROBUSTNESS_FIGURES = "img/robustness"  # under docs/: its figures, one per env

# The chapter the models and the errata follow. Its text names no book, author or edition
# (it opens "Chapter 7 / Formulation of Equations"), so the citation says what it does name.
CHAPTER = "Chapter 7, *Formulation of Equations*"
SECTIONS = {
    "7.1": "Remarks on Formulating Problems",
    "7.2": "Unconstrained Particle",
    "7.3": "Constrained Particle",
    "7.4": "Example: Two Link Robot Arm",
    "7.5": "Example: Rolling Disk",
}
PROBLEMS = "problems 7/1 to 7/5"


def citation() -> str:
    """The source, as a paragraph for the home page."""
    sections = "; ".join(f"{k} {v}" for k, v in SECTIONS.items())
    return (
        f"**Source.** The models, their conventions and [the errata](errata.md) follow "
        f"{CHAPTER} of a textbook of analytical dynamics (sections {sections}; {PROBLEMS}). "
        "The chapter's text, as this project has it, names neither the book's title nor its "
        "author, so neither is given here; section, equation and problem numbers, e.g. "
        "eq. (7.36) or problem 7/3, refer to that chapter."
    )


def model_source(description: str) -> str:
    """The line that cites where a model comes from: the chapter's sections, figures,
    equations and problems its description names, or the chapter's procedure where it
    names none."""
    cited = r"(?:[Ss]ection|[Pp]roblem|Fig\.|eqs?\.)\s*(?:\(7[./-]\d+\)|7[./-]\d+)"
    named = re.findall(cited, description)
    refs = list(dict.fromkeys(" ".join(n.split()).replace("Problem", "problem") for n in named))
    where = (
        f"as its description cites it: {', '.join(refs)}"
        if refs
        else "formulated by the chapter's procedure (section 7.1)"
    )
    return f"*Source*: {CHAPTER}, {where}; [the home page](../index.md) has the citation."


# ---- an env's arguments ------------------------------------------------------------------
def env_options() -> dict[str, str]:
    """{env option: meaning}: the options `gymnasium.make` takes besides the model's
    parameters. The one reach into the envs package's internals: adapt it here if the list
    moves."""
    from envs.plant import ENV_OPTIONS

    return dict(ENV_OPTIONS)


OPTION_TYPES = {
    "render_mode": "str or None",
    "control_period": "float",
    "substeps": "int",
    "integrator": "str",
    "num_threads": "int",
    "max_input": "float, tuple",
    "randomize": "dict, False or None",
    "observe_params": "bool or tuple",
    "perturb": "dict or None",
}
"""The type of each env option as `gymnasium.make` takes it (an option not listed here is
shown with the type of its default)."""


def option_defaults(env) -> dict[str, str]:
    """The default of each env option as this env was made (its task's values)."""
    from envs.docs import input_units

    u = env.unwrapped
    units = input_units(u.task)
    limits = [
        f"{float(v):.4g} {units.get(n, '')}".strip() for n, v in zip(u.task.actuated, u.max_input)
    ]
    randomize = u.task.randomize
    return {
        "render_mode": "None",
        "control_period": f"{u.control_period:g}",
        "substeps": str(u.substeps),
        "integrator": repr(u.integrator),
        "num_threads": "1",
        "max_input": ", ".join(limits),
        "randomize": "the task's: " + repr(dict(randomize)) if randomize else "None",
        "observe_params": "False",
        "perturb": "None",
    }


def arguments_table(defaults: dict[str, str], parameters: dict, units: dict, docs: dict) -> str:
    """The '## Arguments' table: every env option, then every model parameter by name."""
    cell = lambda text: str(text).replace("|", r"\|").replace("\n", " ")  # noqa: E731
    lines = ["| argument | type | default | meaning |", "|---|---|---|---|"]
    for name, meaning in env_options().items():
        default = defaults.get(name, "")
        kind = OPTION_TYPES.get(name, "")
        lines.append(f"| `{name}` | {kind} | {cell(default)} | {cell(meaning)} |")
    for name, value in parameters.items():
        unit = units.get(name, "")
        meaning = docs.get(name) or "model parameter"
        lines.append(
            f"| `{name}` | float | {float(value):g}{' ' + unit if unit else ''} | "
            f"{cell(meaning)} (model parameter) |"
        )
    return "\n".join(lines)


# ---- versions ----------------------------------------------------------------------------
def version_doc(task, module_name: str) -> str | None:
    """The docstring written under the module variable bound to `task` (an attribute
    docstring, `TASK = Task(...)` followed by a string), or None."""
    module = importlib.import_module(module_name)
    names = {k for k, v in vars(module).items() if v is task}
    tree = ast.parse(Path(module.__file__).read_text(encoding="utf-8"))
    body = tree.body
    for node, after in zip(body, body[1:]):
        targets = getattr(node, "targets", None) or [getattr(node, "target", None)]
        if any(isinstance(t, ast.Name) and t.id in names for t in targets):
            if isinstance(after, ast.Expr) and isinstance(after.value, ast.Constant):
                if isinstance(after.value.value, str):
                    return " ".join(after.value.value.split())
    return None


def version_note(env_id: str, versions: list[str], current: tuple[str, ...], doc: str | None):
    """Markdown above an env page's text: for a superseded version, a warning that links
    the current one; the version's own docstring, where it has one."""
    from_slug = lambda i: i.replace("/", "-")  # noqa: E731
    name = env_id.rsplit("-v", 1)[0]
    newest = next((i for i in current if i.rsplit("-v", 1)[0] == name), versions[-1])
    lines = []
    if env_id != newest:
        lines += [
            '!!! warning "Superseded"',
            f"    {env_id} is kept registered to compare; the current version is "
            f"[{newest}]({from_slug(newest)}.md). The tables, arguments and linearisation "
            f"on this page are {env_id}'s own; the description below is the module's, "
            f"written for {newest}" + (" (this version's differences first)." if doc else "."),
            "",
        ]
    if doc and env_id != newest:  # the current version's text is the module's docstring
        lines += [f'!!! note "About {env_id}"', f"    {doc}", ""]
    return "\n".join(lines)


def versions_section(env_id: str, versions: list[str], current: tuple[str, ...]) -> str:
    """The registered versions of this name, the current one marked."""
    rows = []
    for v in reversed(versions):
        state = "current" if v in current else "superseded, kept registered"
        here = "**this page**" if v == env_id else f"[{v}]({v.replace('/', '-')}.md)"
        rows.append(f"| `{v}` | {state} | {here} |")
    return "\n".join(["| id | status | page |", "|---|---|---|", *rows])


# ---- robustness --------------------------------------------------------------------------
def robustness_page() -> str:
    """The robustness benchmark's results (docs/data/robustness.json, written by
    `benchmarks/robustness.py`) with their date, and the figures."""
    head = [
        "# Robustness",
        "",
        "How the agents fare when the plant is not the controller's model: one quantity at a "
        "time (each inertial parameter, all of them together, observation and torque noise, "
        "motor response, delay, pushes) moves away from the nominal plant over a grid, and "
        "every agent runs the same seeded episodes at every point, with success and its "
        "Wilson 95 % interval. The controllers keep the nominal model. The method, the "
        "grids and the discussion of past runs are in the [results log](results-log.md); "
        "`benchmarks/robustness.py` measures (its `--help` lists the options).",
        "",
        "How to use it: find the deviation you expect on your machine (a mass known to 10 %, "
        "a sensor's noise, a motor's lag) in the tables and read each agent's success there. "
        "Where a controller falls below what you need, fit the model to the machine "
        "([identification](identification.md)) and redesign on it, or train with the "
        "deviation drawn at every reset (`randomize=`, `perturb=`: the "
        "[library](library.md#environments)). To measure your own system: "
        "`python benchmarks/robustness.py --envs ENV_ID`.",
        "",
    ]
    if not ROBUSTNESS.exists():
        body = ["No results file (`docs/data/robustness.json`) yet: copy a run's "
                "`results.json` there (see below).", ""]  # fmt: skip
    else:
        body = robustness_tables(json.loads(ROBUSTNESS.read_text(encoding="utf-8")))
    figures = ["## Figures", ""]
    figures.append(
        "Each panel moves one quantity; the band is the 95 % interval, the grey line 50 %. "
        "These figures come from the larger runs of the results log (100 episodes per grid "
        "point, PPO trained nominally and with randomisation included), not from the run tabulated "
        "above:"
    )
    figures.append("")
    folder = ROOT / "docs" / ROBUSTNESS_FIGURES
    for png in sorted(folder.glob("*.png")):
        label = png.stem.replace("Lagrange-", "Lagrange/") if png.stem != "model-based" else (
            "model-based controllers on deviated plants"
        )  # fmt: skip
        figures += [f"![{label}]({ROBUSTNESS_FIGURES}/{png.name})", ""]
    refresh = [
        "## Refreshing",
        "",
        "```bash",
        "python benchmarks/robustness.py --out runs/robustness --figures docs/img/robustness",
        "cp runs/robustness/results.json docs/data/robustness.json",
        "```",
        "",
    ]
    return "\n".join(head + body + figures + refresh)


def robustness_tables(results: dict) -> list[str]:
    """The benchmark's own report (benchmarks/robustness_report.markdown) under a dated
    heading, its sections one level down."""
    import sys

    sys.path.insert(0, str(ROOT))
    from benchmarks.robustness_report import markdown

    text = markdown(results)
    text = text.split("\n", 1)[1]  # its own title
    text = re.sub(r"^## ", "### ", text, flags=re.M)
    runs = results.get("runs", [])
    dates = sorted({r["date"][:10] for r in runs})
    when = f"Measured {', '.join(dates)}" if dates else "Undated"
    sys.path.insert(0, str(ROOT / "scripts"))
    from docs_data import staleness

    last = runs[-1] if runs else {}
    old = staleness(last.get("commit"), last.get("date", "").replace(" UTC", ""))
    return [f"## Results ({when.lower() if not dates else when})", "", old, text.strip(), ""]
