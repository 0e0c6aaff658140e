"""Generate docs/models.md (and the schematics in docs/img/) from the registered models.

Everything in the page comes from the models themselves: docstrings, coordinates, inputs,
parameters with units, the derived Lagrange equations, constraints and outputs in LaTeX.
Run from the repository root:  python scripts/gen_models_doc.py [--out docs]
"""

from __future__ import annotations

import argparse
import inspect
import io
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import dynamics  # noqa: E402
from dynamics.cache import write_atomic  # noqa: E402


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight", metadata={"Software": None})
    plt.close(fig)
    return buf.getvalue()


def _axes(title: str):
    fig, ax = plt.subplots(figsize=(4.2, 3.2))
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=10)
    ax.axis("off")
    return fig, ax


def sketch_two_link_arm(p: dict) -> bytes:
    th1, th2 = 0.6, 1.4
    fig, ax = _axes("two_link_arm: absolute angles from the downward vertical")
    A = np.zeros(2)
    C = A + p["l"] * np.array([np.sin(th1), -np.cos(th1)])
    D = C + 2 * p["l2"] * np.array([np.sin(th2), -np.cos(th2)])
    ax.plot(*np.c_[A, C], lw=5, color="tab:blue")
    ax.plot(*np.c_[C, D], lw=5, color="tab:orange")
    ax.plot([0, 0], [0, -1.2], "k:", lw=1)
    ax.plot([C[0], C[0]], [C[1], C[1] - 0.9], "k:", lw=1)
    ax.plot(*A, "ks")
    ax.annotate(r"$\theta_1$", (0.12, -0.55))
    ax.annotate(r"$\theta_2$", (C[0] + 0.15, C[1] - 0.45))
    ax.annotate("A (M1)", A + [0.05, 0.08])
    ax.annotate("C (M2)", C + [0.08, 0.0])
    ax.annotate("g", (-0.6, -0.2))
    ax.arrow(-0.5, 0.0, 0, -0.35, width=0.01, color="k")
    return _png(fig)


def sketch_eccentric_disk_slider(p: dict) -> bytes:
    theta = 0.9
    R, l, h, s = p["R"], p["l"], 0.16, 0.5 * p["R"]  # h drawn > 0 to show it
    fig, ax = _axes("eccentric_disk_slider (problem 7/3), h > 0 drawn")
    ax.add_patch(plt.Circle((0, 0), 1.3 * R, fc="0.85", ec="k"))
    P = R * np.array([np.cos(theta), np.sin(theta)])
    G = s * np.array([np.cos(theta), np.sin(theta)])
    xs = P[0] + np.sqrt(l**2 - (P[1] + h) ** 2)
    S = np.array([xs, -h])
    ax.plot(*np.c_[[0, 0], P], "k-", lw=1)
    ax.plot(*np.c_[P, S], lw=3, color="tab:blue")
    ax.plot([-0.2, l + 1.6 * R], [-h - 0.012, -h - 0.012], color="0.3", lw=2)
    ax.add_patch(plt.Rectangle((xs - 0.02, -h - 0.01), 0.04, 0.03, fc="tab:orange", ec="k"))
    ax.plot(0, 0, "k+", ms=10)
    ax.plot(*P, "ko", ms=4)
    ax.plot(*G, "o", color="tab:red", ms=5)
    ax.plot([0, 0.6 * R], [0, 0], "k:", lw=1)
    for label, at in (("O", (-0.03, -0.03)), ("P", P + [0, 0.015]), ("G", G + [-0.03, 0.01])):
        ax.annotate(label, at)
    ax.annotate(r"$\theta$", (0.03, 0.01))
    ax.annotate("S (m)", S + [-0.02, 0.03])
    ax.plot([-0.15, -0.15], [0, -h], "k|-", lw=0.8)
    ax.annotate("h", (-0.19, -h / 2))
    ax.annotate("l", (P + S) / 2 + [0.0, 0.015])
    return _png(fig)


def sketch_particle_on_curve(p: dict) -> bytes:
    fig, ax = _axes("particle_on_curve: y = f(x, t), default k x^2 + A sin(Omega t)")
    x = np.linspace(-1.5, 1.5, 200)
    for phase, style in ((0.0, "-"), (np.pi / 2, "--"), (-np.pi / 2, ":")):
        ax.plot(x, p["k"] * x**2 + p["A"] * np.sin(phase), "k" + style, lw=1)
    x0 = 0.8
    ax.plot(x0, p["k"] * x0**2, "o", color="tab:orange", ms=9)
    ax.annotate("m", (x0 + 0.08, p["k"] * x0**2 - 0.1))
    ax.arrow(-1.2, 1.0, 0, -0.35, width=0.01, color="k")
    ax.annotate("g", (-1.1, 0.8))
    ax.annotate("x", (1.45, -0.12))
    ax.plot([-1.5, 1.5], [0, 0], color="0.6", lw=0.5)
    return _png(fig)


def sketch_bead_on_driven_rod(p: dict) -> bytes:
    phi, r = 0.5, 0.5
    fig, ax = _axes("bead_on_driven_rod: phi above horizontal, r along the rod")
    half = p["rod_length"] / 2
    d = np.array([np.cos(phi), np.sin(phi)])
    ax.plot(*np.c_[-half * d, half * d], lw=4, color="tab:blue")
    ax.plot(0, 0, "ks")
    ax.plot(*(r * d), "o", color="tab:orange", ms=10)
    ax.plot([0, 0.8], [0, 0], "k:", lw=1)
    ax.annotate(r"$\phi$", (0.35, 0.06))
    ax.annotate("r", r * d + [0.0, 0.1])
    ax.annotate(r"O ($\tau$)", (0.02, -0.15))
    return _png(fig)


SKETCHES = {
    "two_link_arm": sketch_two_link_arm,
    "eccentric_disk_slider": sketch_eccentric_disk_slider,
    "particle_on_curve": sketch_particle_on_curve,
    "bead_on_driven_rod": sketch_bead_on_driven_rod,
}


EQUATIONS_NOT_PRINTED = {
    "whipple_bicycle": "Its equations and constraints run to thousands of operations each "
    "and are not printed; `python -m dynamics.bicycle` prints their linearisation "
    "(the benchmark's M, C1, K0, K2).",
}


def display(expr, lhs: str = "", rhs: str = "", width: int = 220) -> str:
    """`lhs expr rhs` as display LaTeX, a long sum broken into aligned lines of about
    `width` LaTeX characters (MathJax and GitHub do not wrap equations)."""
    import sympy as sp
    from sympy.physics.vector.printing import vlatex

    expr = sp.sympify(expr)
    terms = expr.as_ordered_terms() if isinstance(expr, sp.Add) else (expr,)  # print order
    pieces = []
    for i, term in enumerate(terms):
        negative = term.could_extract_minus_sign()
        text = vlatex(-term if negative else term)
        pieces.append(("- " if negative else ("" if i == 0 else "+ ")) + text)
    lines, line = [], lhs
    for piece in pieces:
        if len(line) + len(piece) > width and line.strip() not in ("", lhs.strip()):
            lines.append(line)
            line = ""
        line += (" " if line else "") + piece
    lines.append(line + rhs)
    if len(lines) == 1:
        return f"$$ {lines[0]} $$"
    body = " \\\\\n".join("&" + ln if k == 0 else "& \\quad " + ln for k, ln in enumerate(lines))
    return f"$$\n\\begin{{aligned}}\n{body}\n\\end{{aligned}}\n$$"


def model_section(
    name: str, image: str | None, level: int = 2, images: str = "img/", model=None
) -> str:
    """The Markdown section of one model (its heading at `level`, schematics under `images`;
    the documentation site's model pages start from it too, giving the `model` they built)."""
    from sympy.physics.vector.printing import vlatex

    model = model or dynamics.get_model(name)
    spec = model.spec
    lines = [f"{'#' * level} `{name}`", ""]
    doc = inspect.cleandoc(spec.description or "").splitlines()
    lines += ["```text", *[line.rstrip() for line in doc], "```", ""]
    if image:
        lines += [f"![{name}]({images}{image})", ""]
    lines.append(f"Coordinates: {', '.join(f'`{c}`' for c in model.coordinates)}.  ")
    lines.append(f"Inputs: {', '.join(f'`{u}`' for u in model.inputs) or 'none'}.")
    lines += ["", "| parameter | default | unit | meaning |", "|---|---|---|---|"]
    for sym, par in spec.parameters.items():
        doc = str(par.doc).replace("|", r"\|")  # a '|' would end the cell
        lines.append(f"| `{sym}` | {par.default:g} | {par.unit or '-'} | {doc} |")
    if name in EQUATIONS_NOT_PRINTED:
        return "\n".join([*lines, "", EQUATIONS_NOT_PRINTED[name]]) + "\n"
    lines += ["", "Lagrange's equations (each = 0):", ""]
    lines += [display(eq, rhs=" = 0") + "\n" for eq in model.equations()]
    if spec.constraints:
        lines += ["", "Nonholonomic constraints (each = 0):", ""]
        lines += [display(c, rhs=" = 0") + "\n" for c in spec.constraints]
    if model.derived.outputs:
        lines += ["", "Outputs:", ""]
        lines += [f"- `{k}`: ${vlatex(v).strip()}$" for k, v in model.derived.outputs.items()]
    return "\n".join(lines) + "\n"


def generate(out: Path) -> list[Path]:
    """Write models.md and the schematics under `out`; return the files written."""
    written = []
    sections = []
    for name in dynamics.list_models():
        image = None
        if name in SKETCHES:
            image = f"{name}.png"
            path = out / "img" / image
            write_atomic(path, SKETCHES[name](dynamics.get_model(name).parameters))
            written.append(path)
        print(f"  {name}", file=sys.stderr)
        sections.append(model_section(name, image))
    header = (
        "# The models\n\n"
        "Generated by `scripts/gen_models_doc.py` from the registered models (do not edit by\n"
        "hand; rerun the script). Each model's equations are derived by `dynamics.derive`;\n"
        "the book's misprints they expose are in [errata.md](errata.md).\n\n"
        + "\n".join(f"- [`{n}`](#{n})" for n in dynamics.list_models())
        + "\n\n"
    )
    page = out / "models.md"
    write_atomic(page, (header + "\n".join(sections)).encode("utf-8"))
    written.append(page)
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs", help="output directory")
    args = parser.parse_args(argv)
    for path in generate(args.out):
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
