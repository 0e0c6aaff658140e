"""The documentation site's generated pages: mkdocs runs this file as its hooks (mkdocs.yml).

Nothing on those pages is copied by hand. At every build it writes, from the code:
- one page per registered `Lagrange/*` id (every version) from its task declaration and its
  module's docstring, with the spaces of `gymnasium.make(id)`, an animation under a
  baseline agent, and the agents benchmark's numbers with their date and machine;
- one page per registered model from its derivation (through scripts/gen_models_doc.py),
  with T, V, the generalised forces, the linearisation at the operating point of each env
  on it, and the errata whose tests check it;
- the benchmark page and an API reference page per module (mkdocstrings).
New ids and models appear by themselves. The animations take seconds each, so they are
rendered by a command and committed under docs/assets/envs/; one that is missing is
rendered during the build instead (and the build says so):

    python scripts/docs_site.py gifs [ID ...]     # (re)render the animations
"""

from __future__ import annotations

import argparse
import ast
import functools
import hashlib
import importlib
import importlib.util
import inspect
import io
import json
import logging
import pkgutil
import re
import sys
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

DOCS = ROOT / "docs"
ASSETS = DOCS / "assets" / "envs"  # committed animations: <slug>.gif and <slug>.json
RESULTS = DOCS / "data" / "agents.json"  # written by benchmarks/baselines.py --results
NAMESPACE = "Lagrange/"
PACKAGES = ("dynamics", "envs", "agents")
GIF_WIDTH = 480  # pixels: the animations as rendered and shown on each env page
BASELINES = ("plan", "lqr", "heuristic")  # agents that need no training, best first on ties
log = logging.getLogger("mkdocs.hooks.docs_site")


# ---- what the code registers -------------------------------------------------------------
def env_ids() -> list[str]:
    """Every registered Lagrange id, every version, grouped by name."""
    import gymnasium as gym

    import envs  # noqa: F401  (registers the namespace)

    ids = [k for k in gym.registry if k.startswith(NAMESPACE)]
    return sorted(ids, key=lambda i: (i.rsplit("-v", 1)[0], int(i.rsplit("-v", 1)[1])))


@functools.cache
def model_names() -> list[str]:
    import dynamics

    return list(dynamics.list_models())


@functools.cache
def model(name: str):
    """The registered model `name`, built once per build (its spec is then built once)."""
    import dynamics

    return dynamics.get_model(name)


@functools.cache
def sibling(name: str):
    """scripts/<name>.py (the models page's generator, the guides' pages) as a module."""
    spec = importlib.util.spec_from_file_location(name, ROOT / "scripts" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def models_doc():
    """scripts/gen_models_doc.py, the models page's generator, as a module."""
    return sibling("gen_models_doc")


def guides():
    """scripts/docs_guides.py: the robustness, agents and citation pieces."""
    return sibling("docs_guides")


def cached_text(kind: str, parts: tuple[str, ...], build) -> str:
    """`build()`'s text, kept on disk in the model cache's folder (docs/) under a hash of
    `parts`: the derived display forms take seconds to minutes per model, and are the same
    until the model, sympy or their generator changes. Written atomically."""
    from dynamics.cache import cache_dir, write_atomic

    key = hashlib.sha256("\n\0".join(parts).encode("utf-8")).hexdigest()
    path = cache_dir() / "docs" / f"{kind}_{key[:24]}.md"
    if path.is_file():
        return path.read_text(encoding="utf-8")
    text = build()
    write_atomic(path, text)
    return text


def slug(env_id: str) -> str:
    return env_id.replace("/", "-")


def task_of(env_id: str):
    import gymnasium as gym

    import envs  # noqa: F401

    return gym.spec(env_id).kwargs["task"]


def model_name(task) -> str | None:
    """The registered model a task runs on (None for an unregistered one)."""
    model = task.model
    name = model if isinstance(model, str) else getattr(model, "name", None)
    return name if name in model_names() else None


def documented(task) -> tuple[str, str]:
    """(module name, the module's docstring with the tables generated for `task`).

    The one place that reaches into the envs' docstring generator: re-point it here when
    that moves."""
    from envs.docs import document

    functions = (task.reward, task.success, *(getattr(t, "fn", None) for t in task.terms))
    module = next(inspect.getmodule(f) for f in functions if callable(f))
    return module.__name__, document(inspect.getdoc(module) or "", task)


@functools.cache
def documented_id(env_id: str) -> tuple[str, str]:
    """`documented(task_of(env_id))`, once per build."""
    return documented(task_of(env_id))


# ---- Markdown formatting -----------------------------------------------------------------
def escape_text(markdown: str) -> str:
    """Docstring prose as Markdown: outside code, a '*' (N*m, theta1*) is literal unless it
    marks a list item; code spans may run over line ends, fenced blocks are left alone."""
    chunks = re.split(r"(^```.*?^```[^\n]*$)", markdown, flags=re.S | re.M)
    for k in range(0, len(chunks), 2):  # the even chunks are outside fenced blocks
        parts = chunks[k].split("`")
        for i in range(0, len(parts), 2):  # the even parts are outside code spans
            parts[i] = parts[i].replace("*", r"\*")
            parts[i] = re.sub(r"^(\s*)\\\*(?= )", r"\1*", parts[i], flags=re.M)
        chunks[k] = "`".join(parts)
    return "".join(chunks)


def sections(doc: str) -> tuple[str, dict[str, str]]:
    """A Gymnasium-style docstring: (its summary, {'## ' heading: body})."""
    summary, *rest = re.split(r"^## ", doc, flags=re.M)
    found = {}
    for part in rest:
        title, _, body = part.partition("\n")
        found[title.strip()] = body.strip("\n")
    return summary.strip(), found


NOISE = 1e-9
"""Entries of a linearisation below this fraction of its largest entry print as 0: the
exact Jacobians evaluated in floating point leave rounding residue (1e-33, -0.0) where the
symbolic entry is zero."""


EIGEN_NOISE = 1e-7
"""The same for eigenvalues: a repeated eigenvalue (the bicycle's zero ones) splits by about
the square root of the rounding error, 1.5e-8 relative, in floating point."""


def number(v: float, scale: float = 1.0, digits: int = 4, noise: float = NOISE) -> str:
    """`v` to `digits` significant digits; 0 (never -0) below `noise` x `scale`."""
    if abs(v) < noise * max(scale, 1.0):
        return "0"
    text = f"{v:.{digits}g}"
    return "0" if float(text) == 0 else text


def latex_matrix(M, digits: int = 4) -> str:
    import numpy as np

    M = np.atleast_2d(np.asarray(M, float))
    scale = float(np.abs(M).max(initial=0.0))

    def num(v: float) -> str:
        mantissa, e, exponent = number(v, scale, digits).partition("e")
        return mantissa + (f" \\times 10^{{{int(exponent)}}}" if e else "")

    rows = [" & ".join(num(v) for v in row) for row in M]
    return r"\begin{bmatrix}" + r" \\ ".join(rows) + r"\end{bmatrix}"


def benchmark() -> dict | None:
    """The agents benchmark: {"runs": [what measured, ...], "rows": [...]}, each row naming
    its run by index (benchmarks/baselines.py writes it)."""
    return json.loads(RESULTS.read_text(encoding="utf-8")) if RESULTS.exists() else None


def measured_on(results: dict) -> str:
    """When, how and on what machine one run of the benchmark measured its rows."""
    m = results["machine"]
    versions = ", ".join(f"{k} {v}" for k, v in m.get("versions", {}).items())
    old = data().staleness(results.get("commit"), results["finished"])
    return (old + "\n" if old else "") + (
        f"Measured {results['finished'][:10]} ({results['started']} to {results['finished']}, "
        f"{results['wall_s'] / 60:.0f} min) by `{results['command']}`: {results['episodes']} "
        f"episodes per agent, seeds {results['seed']}..{results['seed'] + results['episodes'] - 1}"
        f", on {m['cpu']}, {m['cores']} cores, {m['memory_gib']} GiB, {m['os']}, Python "
        f"{m['python']} ({versions}; OMP_NUM_THREADS={m.get('threads')})."
    )


def results_table(rows: list[dict]) -> str:
    """The benchmark's rows as a table: success and return with their 95 % intervals, how
    the episodes ended, mean length, training."""

    def pct(r, key):
        return f"{float(r[key]):.0%}"

    head = ["agent", "success [95 % CI]", "return [95 % CI]", "ended S / F / D / T", "length"]
    head.append("training")
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        train = (
            f"{r['algo']}, {float(r['timesteps']) / 1e6:.2g}M steps, {float(r['train_s']):.0f} s"
            if r.get("algo")
            else ""
        )
        note = f"<br>{r['note']}" if r.get("note") else ""
        cells = [
            f"`{r['agent']}`{note}",
            f"{pct(r, 'success_rate')} [{pct(r, 'success_low')}, {pct(r, 'success_high')}]",
            f"{float(r['mean_return']):.1f} [{float(r['return_low']):.1f}, "
            f"{float(r['return_high']):.1f}]",
            " / ".join(r[k] for k in ("n_success", "n_failure", "n_diverged", "n_time_limit")),
            f"{float(r['mean_length']):.0f}",
        ]
        cells.append(train)
        lines.append("| " + " | ".join(cells) + " |")
    legend = (
        "Ended: episodes that ended in success (S), failure (F: the task terminated them), "
        "divergence (D) or at the time limit (T)."
    )
    return "\n".join(lines) + "\n\n" + legend


# ---- the environments' live facts --------------------------------------------------------
def operating_point(env):
    """(x0, u0) the task regulates to, after reset (the env's public contract)."""
    return env.unwrapped.operating_point()


@functools.cache
def env_facts(env_id: str) -> dict:
    """What `gymnasium.make(env_id)` shows: spaces, limits, the operating point after
    reset(seed=0) and the linearisation there (None where the task declares none)."""
    import gymnasium as gym
    import numpy as np

    from agents.control.linear import linearize, state_names

    with warnings.catch_warnings():  # an older version's deprecation notice is no news here
        warnings.simplefilter("ignore", DeprecationWarning)
        env = gym.make(env_id)
    env.reset(seed=0)
    u = env.unwrapped
    facts = {
        "action_space": env.action_space,
        "observation_space": env.observation_space,
        "max_episode_steps": env.spec.max_episode_steps,
        "control_period": float(u.control_period),
        "system": u.system,
        "defaults": guides().option_defaults(env),
        "parameters": dict(u.system.parameters),
        "lin": None,
    }
    try:
        x0, u0 = operating_point(env)
    except (ValueError, TypeError, NotImplementedError) as exc:
        facts["no_lin"] = str(exc)
    else:
        lin = linearize(u.system, np.asarray(x0, float), np.asarray(u0, float))
        facts["lin"] = lin
        facts["states"] = state_names(u.system)
    env.close()
    return facts


def linearisation_section(env_id: str, level: str = "##") -> str:
    import numpy as np

    facts = env_facts(env_id)
    lin = facts["lin"]
    if lin is None:
        return f"{level} Linearisation\n\nNo operating point declared ({facts['no_lin']}).\n"
    names = ", ".join(f"`{s}`" for s in lin.states)
    eig = np.linalg.eigvals(lin.A)
    scale = float(np.abs(eig).max(initial=0.0))
    real = [number(e.real, scale, noise=EIGEN_NOISE) for e in eig]
    imag = [number(abs(e.imag), scale, noise=EIGEN_NOISE) for e in eig]
    eigs = ", ".join(
        r if i == "0" else f"{r} {'-' if e.imag < 0 else '+'} {i}i"
        for r, i, e in zip(real, imag, eig)
    )
    x0 = ", ".join(number(v) for v in lin.x0)
    u0 = ", ".join(number(v) for v in lin.u0)
    return (
        f"{level} Linearisation at the operating point\n\n"
        f"About the operating point after `reset(seed=0)` (the task's `operating_point`): "
        f"x0 = ({x0}) over ({names}), inputs u0 = ({u0}) over "
        f"({', '.join(f'`{s}`' for s in lin.inputs)}) holding it; "
        "d(dx)/dt = A dx + B du from the derived model's exact Jacobians "
        "(`agents.control.linear.linearize`; B has a column per model input, the action drives "
        f"{', '.join(f'`{a}`' for a in task_of(env_id).actuated)}):\n\n"
        f"$$ A = {latex_matrix(lin.A)}, \\quad B = {latex_matrix(lin.B)} $$\n\n"
        f"Eigenvalues of A (1/s): {eigs}.\n"
    )


# ---- animations --------------------------------------------------------------------------
def choose_agent(env_id: str, results: dict | None) -> str:
    """The baseline to animate: the untrained agent with the best measured success, else
    the task's heuristic, else LQR."""
    rows = [r for r in (results or {}).get("rows", []) if r["env_id"] == env_id]
    scored = {r["agent"]: float(r["success_rate"]) for r in rows if r["agent"] in BASELINES}
    if scored:
        return max(BASELINES, key=lambda a: (scored.get(a, -1.0), -BASELINES.index(a)))
    return "heuristic" if task_of(env_id).heuristic is not None else "lqr"


def render_animation(env_id: str, agent: str, seed: int = 0, width: int = GIF_WIDTH, frames_max=80):
    """(GIF bytes, facts) of one episode of `agent` from reset(seed) in real time, until 2 s
    after the first success (4 s at least), the episode's end, or 15 s: at most
    `frames_max` frames."""
    import gymnasium as gym
    import numpy as np
    from PIL import Image

    from agents.evaluate import make_agent

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        env = gym.make(env_id, render_mode="rgb_array")
    policy = make_agent(agent, env, seed)
    obs, _ = env.reset(seed=seed)
    dt = float(env.unwrapped.control_period)
    frames, step, first_success, done = [env.render()], 0, None, False
    while not done and step * dt < 15.0:
        action, _ = policy.predict(obs, deterministic=True)
        obs, _, terminated, truncated, info = env.step(np.asarray(action))
        step += 1
        if info.get("is_success") and first_success is None:
            first_success = step * dt
        frames.append(env.render())
        done = (
            terminated
            or truncated
            or (first_success is not None and step * dt >= max(first_success + 2.0, 4.0))
        )
    env.close()
    stride = max(2, -(-len(frames) // frames_max))
    frames = frames[::stride]
    h = round(width * frames[0].shape[0] / frames[0].shape[1])
    images = [
        Image.fromarray(f).resize((width, h), Image.LANCZOS).quantize(32, dither=Image.Dither.NONE)
        for f in frames
    ]
    buf = io.BytesIO()
    images[0].save(
        buf,
        format="GIF",
        save_all=True,
        append_images=images[1:],
        loop=0,
        duration=round(1000 * stride * dt),
        optimize=True,
    )
    facts = {
        "env_id": env_id,
        "agent": agent,
        "seed": seed,
        "shown_s": round(step * dt, 2),
        "success_at_s": None if first_success is None else round(first_success, 2),
        "ended": "terminated" if done and terminated else "",
    }
    return buf.getvalue(), facts


def animation(env_id: str) -> tuple[bytes | None, dict]:
    """The committed animation's facts (bytes None), or a fresh rendering when missing."""
    sidecar = ASSETS / f"{slug(env_id)}.json"
    if (ASSETS / f"{slug(env_id)}.gif").exists() and sidecar.exists():
        return None, json.loads(sidecar.read_text(encoding="utf-8"))
    log.info("rendering %s's animation (run `python scripts/docs_site.py gifs` to keep it)", env_id)
    return render_animation(env_id, choose_agent(env_id, benchmark()))


def write_animations(ids: list[str]) -> None:
    import envs  # noqa: F401  (registers the namespace when ids are given)
    from dynamics.cache import write_atomic

    results = benchmark()
    for env_id in ids:
        gif, facts = render_animation(env_id, choose_agent(env_id, results))
        write_atomic(ASSETS / f"{slug(env_id)}.gif", gif)
        write_atomic(ASSETS / f"{slug(env_id)}.json", (json.dumps(facts, indent=1) + "\n").encode())
        print(
            f"{env_id}: {facts['agent']}, {len(gif) / 1024:.0f} KiB, shown {facts['shown_s']} s,"
            f" success at {facts['success_at_s']} s"
        )


# ---- pages -------------------------------------------------------------------------------
def env_page(env_id: str, anim: dict) -> str:
    import gymnasium as gym

    task = task_of(env_id)
    spec = gym.spec(env_id)
    name = env_id.rsplit("-v", 1)[0]
    module, doc = documented_id(env_id)
    summary, parts = sections(escape_text(doc))
    summary = re.sub(rf"^{re.escape(name)}-v\d+[^:]*: ", "", summary)  # the title names it
    summary = summary[:1].upper() + summary[1:]
    facts = env_facts(env_id)
    model = model_name(task)
    versions = [i for i in env_ids() if i.rsplit("-v", 1)[0] == name]
    obs = facts["observation_space"]
    seconds = facts["max_episode_steps"] * facts["control_period"]
    if anim["success_at_s"] is not None:
        outcome = f"success (the task's criterion) from {anim['success_at_s']:.2f} s"
    else:
        outcome = "no success in the frames shown"
    own = guides().version_doc(task, module)
    own = escape_text(own) if own else None  # N*m is no emphasis
    lines = [
        f"# {env_id}",
        "",
        guides().version_note(env_id, versions, current_ids(), own),
        summary,
        "",
        f'<figure markdown="span">\n  ![{env_id} under {anim["agent"]}]'
        f'(../assets/envs/{slug(env_id)}.gif){{ width="{GIF_WIDTH}" }}\n'
        f"  <figcaption>Agent <code>{anim['agent']}</code> from <code>reset(seed="
        f"{anim['seed']})</code>, first {anim['shown_s']:.1f} s: {outcome}.</figcaption>\n"
        "</figure>",
        "",
        f'- **Make**: `gymnasium.make("{env_id}")`',
        f"- **Action space**: `{facts['action_space']}`",
        f"- **Observation space**: `Box(low, high, {obs.shape}, {obs.dtype})` (table below)",
        f"- **Episode limit**: {facts['max_episode_steps']} steps of "
        f"{facts['control_period']:g} s ({seconds:g} s)",
        "- **Model**: " + (f"[`{model}`](../models/{model}.md)" if model else "unregistered"),
        f"- **Declared in**: `{module}`; entry points `{spec.entry_point}` and "
        f"`{spec.vector_entry_point}` (vector)",
        "- **Versions**: "
        + ", ".join(f"**{v}**" if v == env_id else f"[{v}]({slug(v)}.md)" for v in versions),
        "",
        "```python",
        "import gymnasium as gym",
        "import envs  # registers the Lagrange namespace",
        "",
        f'env = gym.make("{env_id}", render_mode="rgb_array")',
        f'vec = gym.make_vec("{env_id}", num_envs=1024,',
        '                   vectorization_mode="vector_entry_point")',
        f'env = gym.make("envs:{env_id}")  # or let Gymnasium import the package',
        "```",
        "",
    ]
    for title, body in parts.items():
        if title == "Arguments":
            body += "\n\n" + arguments(env_id)
        elif title == "Version History":
            body += "\n\n" + guides().versions_section(env_id, versions, current_ids())
        lines += [f"## {title}", "", body, ""]
    lines.append(linearisation_section(env_id))
    lines += ["## Measured baselines", ""]
    lines.append(lqr_region(env_id))
    results = benchmark()
    rows = [r for r in (results or {}).get("rows", []) if r["env_id"] == env_id]
    if rows:
        lines += [measured_on(results["runs"][rows[0]["run"]]), "", results_table(rows), ""]
    else:
        lines += [
            "This id is not in the agents benchmark (it runs the current version of each "
            "task, `envs.ENV_IDS`).",
            "",
        ]
    return "\n".join(lines)


def current_ids() -> tuple[str, ...]:
    """The current version of each built-in task (`envs.ENV_IDS`)."""
    import envs

    return tuple(envs.ENV_IDS)


def arguments(env_id: str) -> str:
    """The arguments table: every `gymnasium.make` option with its type, this id's default
    and its meaning, then the model's parameters with their units."""
    facts = env_facts(env_id)
    name = model_name(task_of(env_id))
    meta = model_meta(name) if name else {"units": {}, "docs": {}}
    units, docs = meta["units"], meta["docs"]
    table = guides().arguments_table(facts["defaults"], facts["parameters"], units, docs)
    return f'`gymnasium.make("{env_id}", **arguments)` takes:\n\n{table}'


def lqr_region(env_id: str) -> str:
    from agents.lqr import start_region

    task = task_of(env_id)
    facts = env_facts(env_id)
    states = task.lqr.states or (facts["states"] if facts["lin"] is not None else ())
    if not states:
        return ""
    region = start_region(task.lqr, states)
    cells = ", ".join(f"`{k}` ± {v:g}" for k, v in region.items())
    return (
        f"LQR's region (the task's `LQRHints`): uniform perturbations of the operating point "
        f"within {cells}, where LQR is expected to succeed (`python -m agents.lqr {env_id}` "
        "measures it). The benchmark below starts every agent from the task's own start "
        "distribution.\n"
    )


def derived_text(name: str) -> str:
    """The model page's derived part (description, parameters, equations, T, V, Q) in
    Markdown with LaTeX: cached on disk by the model's key (`Model.key`: its source and
    sympy's version), sympy's version and the source of the code that prints it."""
    import sympy

    parts = (
        model(name).key,
        sympy.__version__,
        (ROOT / "scripts" / "gen_models_doc.py").read_text(encoding="utf-8"),
        inspect.getsource(_derived_text),
    )
    return cached_text(f"model_{name}", parts, lambda: _derived_text(name))


def _derived_text(name: str) -> str:
    from sympy.physics.vector.printing import vlatex

    spec = model(name).spec
    image = f"{name}.png" if (DOCS / "img" / f"{name}.png").exists() else None
    display = models_doc().display
    section = models_doc().model_section(name, image, level=1, images="../img/", model=model(name))
    lines = [section.replace("```text\n", "```{.text .prose}\n", 1)]  # wraps (extra.css)
    lines += [
        "## Energies and forces",
        "",
        display(spec.kinetic, lhs="T ="),
        "",
        display(spec.potential, lhs="V ="),
        "",
    ]
    if spec.forces:
        lines += ["Generalised (non-conservative) forces:", ""]
        lines += [display(f, lhs=f"Q_{{{vlatex(q)}}} =") + "\n" for q, f in spec.forces.items()]
    else:
        lines.append("No non-conservative generalised forces.")
    lines.append("")
    if spec.prescribed:
        lines += ["Prescribed (rheonomic) coordinates:", ""]
        lines += [f"$$ {vlatex(q)} = {vlatex(f)} $$\n" for q, f in spec.prescribed.items()]
        lines.append("")
    return "\n".join(lines)


def model_meta(name: str) -> dict:
    """A model's coordinates, inputs, parameter units and docs and its description, cached on
    disk like its derived text: building a spec runs its factory's sympy (seconds for the
    bicycle), which a warm build should not repeat."""
    import sympy

    parts = (model(name).key, sympy.__version__, inspect.getsource(_model_meta))
    return json.loads(cached_text(f"meta_{name}", parts, lambda: json.dumps(_model_meta(name))))


def _model_meta(name: str) -> dict:
    m = model(name)
    spec = m.spec
    return {
        "coordinates": list(m.coordinates),
        "inputs": list(m.inputs),
        "units": {str(k): p.unit for k, p in spec.parameters.items()},
        "docs": {str(k): p.doc for k, p in spec.parameters.items()},
        "description": spec.description or "",
    }


def model_page(name: str) -> str:
    text = derived_text(name)
    heading, _, rest = text.partition("\n")
    source = guides().model_source(model_meta(name)["description"])
    lines = [heading, "", source, rest]
    on_it = [i for i in env_ids() if model_name(task_of(i)) == name]
    if on_it:
        lines += ["## Environments on this model", ""]
        lines += [f"- [{i}](../envs/{slug(i)}.md)" for i in on_it]
        lines.append("")
        lines += [
            linearisation_section(i, "###").replace(
                "### Linearisation at the operating point",
                f"### Linearisation at the operating point of {i}",
            )
            for i in on_it
        ]
    lines += ["## Errata that concern it", ""]
    found = errata_of(name)
    if found:
        lines += [
            "From [the errata](../errata.md): the entries whose tests derive this model.",
            "",
            *found,
        ]
    else:
        lines += ["None of [the errata](../errata.md) is checked on this model.", ""]
    return "\n".join(lines)


@functools.cache
def _test_source(ref: str, names: tuple[str, ...]) -> str:
    """The source of test `path::function`, or its whole file when the function reaches the
    model through a fixture (names no model itself)."""
    path, _, func = ref.partition("::")
    source = (ROOT / path).read_text(encoding="utf-8")
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.FunctionDef) and node.name == func:
            segment = ast.get_source_segment(source, node) or ""
            if any(f'"{n}"' in segment or f"'{n}'" in segment for n in names):
                return segment
    return source


def errata_of(name: str) -> list[str]:
    """The tables of docs/errata.md cut to the rows that name `name` or whose tests derive
    it (each table keeps its own header)."""
    names = model_names()
    tables: dict[str, list[str]] = {}
    header = None
    for line in (DOCS / "errata.md").read_text(encoding="utf-8").splitlines():
        if line.startswith("| #"):
            header = line
            continue
        if header is None or not line.startswith("| ") or line.startswith("|---"):
            continue
        refs = re.findall(r"tests/[\w/]+\.py(?:::\w+)?", line)
        found = [r for r in refs if (ROOT / r.split("::")[0]).exists()]
        sources = [_test_source(r, tuple(names)) for r in found]
        quoted = [f'"{name}"', f"'{name}'"]
        if f"`{name}`" in line or any(q in src for src in sources for q in quoted):
            tables.setdefault(header, []).append(line)
    out = []
    for head, rows in tables.items():
        out += [head, "|" + "---|" * (head.count("|") - 1), *rows, ""]
    return out


def envs_index(anims: dict[str, dict]) -> str:
    lines = [
        "# Environments",
        "",
        "Every registered `Lagrange/*` id, every version; each page is generated from the "
        "task's declaration, its module's docstring and `gymnasium.make`.",
        "",
        "| | id and task | model | spaces |",
        "|---|---|---|---|",
    ]
    for env_id in env_ids():
        task = task_of(env_id)
        summary = sections(documented_id(env_id)[1])[0].split(":", 1)[-1].strip()
        summary = escape_text(" ".join(summary.split()))
        facts = env_facts(env_id)
        model = model_name(task)
        n_a, n_o = facts["action_space"].shape[-1], facts["observation_space"].shape[-1]
        lines.append(
            f'| ![{env_id}](../assets/envs/{slug(env_id)}.gif){{ width="160" }} '
            f"| [{env_id}]({slug(env_id)}.md)<br>{summary} | "
            + (f"[{model}](../models/{model}.md)" if model else "")
            + f" | {n_a} actions, {n_o} observations |"
        )
    return "\n".join(lines) + "\n"


def models_index() -> str:
    lines = [
        "# Models",
        "",
        "Every registered model (`dynamics.list_models()`); each page is derived from its "
        "`ModelSpec` at build time. The book's misprints are in [the errata](../errata.md).",
        "",
        "| model | coordinates | inputs | environments |",
        "|---|---|---|---|",
    ]
    for name in model_names():
        m = model_meta(name)
        on_it = [
            f"[{i}](../envs/{slug(i)}.md)" for i in env_ids() if model_name(task_of(i)) == name
        ]
        lines.append(
            f"| [`{name}`]({name}.md) | {', '.join(f'`{c}`' for c in m['coordinates'])} | "
            f"{', '.join(f'`{u}`' for u in m['inputs']) or '-'} | {', '.join(on_it)} |"
        )
    return "\n".join(lines) + "\n"


def benchmark_page() -> str:
    results = benchmark()
    if results is None:
        return "# Agents benchmark\n\nNo results file (docs/data/agents.json) yet.\n"
    runs, sections = results["runs"], []
    for env_id in dict.fromkeys(r["env_id"] for r in results["rows"]):
        rows = [r for r in results["rows"] if r["env_id"] == env_id]
        when = f"{measured_on(runs[rows[0]['run']])}\n\n" if len(runs) > 1 else ""
        sections.append(f"## [{env_id}](envs/{slug(env_id)}.md)\n\n{when}{results_table(rows)}\n")
    return (
        "# Agents benchmark\n\n"
        "Every agent on every current environment (`envs.ENV_IDS`), scored on the same seeded "
        "episodes: success with its 95 % Wilson interval, mean return with its 95 % Student t "
        "interval, how the episodes ended. The numbers are read from `docs/data/agents.json`, "
        "which `python benchmarks/baselines.py --results docs/data/agents.json` writes (with "
        "`--envs`, only those envs' rows are measured again; each env's section then says "
        "which run measured it).\n\n"
        + (f"{measured_on(runs[0])}\n\n" if len(runs) == 1 else "")
        + "\n".join(sections)
    )


def modules() -> list[str]:
    """The public modules of the packages (no private or __main__ ones)."""
    names = []
    for package in PACKAGES:
        names.append(package)
        path = [str(ROOT / package)]
        for info in pkgutil.walk_packages(path, prefix=f"{package}."):
            if not any(p.startswith("_") for p in info.name.split(".")):
                names.append(info.name)
    return names


def reference_page(module: str) -> str:
    return f"# `{module}`\n\n::: {module}\n"


def pages() -> tuple[dict[str, str], dict[str, bytes]]:
    """({page path: Markdown}, {asset path: bytes}) generated for the site."""
    texts, blobs, anims = {}, {}, {}
    for env_id in env_ids():
        gif, anims[env_id] = animation(env_id)
        if gif is not None:
            blobs[f"assets/envs/{slug(env_id)}.gif"] = gif
        texts[f"envs/{slug(env_id)}.md"] = env_page(env_id, anims[env_id])
    texts["envs/index.md"] = envs_index(anims)
    for name in model_names():
        texts[f"models/{name}.md"] = model_page(name)
    texts["models/index.md"] = models_index()
    texts["benchmark.md"] = benchmark_page()
    texts["robustness.md"] = guides().robustness_page()
    for module in modules():
        texts[f"reference/{module}.md"] = reference_page(module)
    return texts, blobs


# ---- mkdocs hooks ------------------------------------------------------------------------
def on_config(config):
    """The navigation: mkdocs.yml's (home and the guides), then the generated sections."""
    if sys.path[0] != str(ROOT):  # mkdocs restores sys.path after loading this file
        sys.path.insert(0, str(ROOT))
    config["nav"] = list(config.get("nav") or []) + [
        {"Environments": ["envs/index.md"] + [{i: f"envs/{slug(i)}.md"} for i in env_ids()]},
        {"Models": ["models/index.md"] + [{m: f"models/{m}.md"} for m in model_names()]},
        {"API reference": [{m: f"reference/{m}.md"} for m in modules()]},
    ]
    return config


def on_files(files, config):
    from mkdocs.structure.files import File

    texts, blobs = pages()
    for path, content in {**texts, **blobs}.items():
        files.append(File.generated(config, path, content=content))
    return files


def main_job_cost() -> str:
    """What the main job cost: its last stored run (docs/data/main-job.json), else the agents
    benchmark's first run (docs/data/agents.json), dated, with its command and machine."""
    measured = data().main_job_section()
    if measured is not None:
        return measured
    results = benchmark()
    if results is None:
        return "No measurement yet (`docs/data/agents.json`)."
    run = results["runs"][0]
    m = run["machine"]
    return (
        f"The agents benchmark ran it whole with {run['episodes']} episodes per agent in "
        f"{run['wall_s'] / 60:.0f} minutes on {m['cores']} cores ({m['cpu']}), measured "
        f"{run['finished'][:10]} by `{run['command']}`; every table of it is on the "
        f"[agents benchmark](benchmark.md) page.\n\n"
        + data().staleness(run.get("commit"), run["finished"])
    )


def data():
    """scripts/docs_data.py: the data files' ages and the learning table."""
    return sibling("docs_data")


def on_page_markdown(markdown, page, config, files):
    """The pages' rendered data (the learning benchmark's table, the main job's cost), the
    home page's environment gallery, from the registry, and the source's citation."""
    if page.file.src_uri == "learning.md":
        markdown = markdown.replace("<!-- data: learning -->", data().learning_section())
        return markdown.replace("<!-- data: precision -->", data().precision_section())
    if page.file.src_uri != "index.md":
        return markdown
    markdown = markdown.replace("<!-- data: main job -->", main_job_cost())
    markdown = markdown.replace("<!-- source -->", guides().citation())
    cells = [
        f'<a class="env-card" href="envs/{slug(i)}/"><img src="assets/envs/{slug(i)}.gif" '
        f'alt="{i}" width="240"><span>{i}</span></a>'
        for i in env_ids()
    ]
    table = '<div class="env-gallery">\n' + "\n".join(cells) + "\n</div>"
    return markdown.replace("<!-- gallery -->", table)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    gifs = sub.add_parser("gifs", help="render the env animations into docs/assets/envs/")
    gifs.add_argument("ids", nargs="*", help="ids (default: every registered Lagrange id)")
    sub.add_parser("pages", help="list the pages the site generates")
    args = parser.parse_args(argv)
    if args.command == "gifs":
        write_animations(args.ids or env_ids())
    else:
        print(
            "\n".join(
                [
                    *(f"envs/{slug(i)}.md" for i in env_ids()),
                    *(f"models/{m}.md" for m in model_names()),
                    *(f"reference/{m}.md" for m in modules()),
                ]
            )
        )
    return 0


if __name__ == "__main__":
    importlib.invalidate_caches()
    sys.exit(main())
