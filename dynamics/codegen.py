"""Code generation: derived equations -> a Python module of numba kernels.

Each group of expressions is reduced by sympy's common-subexpression elimination and printed
as straight-line scalar code (`math` functions) that writes into output arrays. The fixed
kernels in `kernels.py` (linear solve, right-hand side, batched RK4 with constraint
projection, batched energy...) are appended to the same module so that numba's on-disk cache
can hold the whole model. See benchmarks/dynamics.py for why numba and not numpy or C.
"""

from __future__ import annotations

from pathlib import Path

import sympy as sp
import sympy.physics.mechanics as me
from sympy.printing.numpy import NumPyPrinter
from sympy.printing.pycode import PythonCodePrinter

from .derive import Derived
from .spec import t

KERNELS = Path(__file__).with_name("kernels.py")


class _Printer(PythonCodePrinter):
    def _print_Symbol(self, expr):  # names are already valid identifiers
        return expr.name


class _LanePrinter(_Printer):
    """Scalar code that LLVM can run several rows at a time: sin and cos by the kernels'
    branch-free `vsin`/`vcos` (libm's are calls, which numba never vectorises), small
    integer powers as products."""

    def _print_sin(self, expr):
        return f"vsin({self._print(expr.args[0])})"

    def _print_cos(self, expr):
        return f"vcos({self._print(expr.args[0])})"

    def _print_Pow(self, expr, rational=False):
        base, e = expr.args
        if e.is_Integer and 1 <= abs(int(e)) <= 4:
            product = "*".join([f"({self._print(base)})"] * abs(int(e)))
            return product if e > 0 else f"(1.0/({product}))"
        return super()._print_Pow(expr, rational)


class _VectorPrinter(NumPyPrinter):
    def _print_Symbol(self, expr):
        return expr.name


def _vectorized(targets_count: int, exprs: list, header: list[str]) -> str:
    """`kkt_columns(t, x, u, p)`: the entries of the KKT matrix and right-hand side as numpy
    expressions over columns (x has shape (2n, N)); constant entries stay Python floats."""
    printer = _VectorPrinter({"fully_qualified_modules": True})
    lines = ["", "", "def kkt_columns(t, x, u, p):"]
    lines += ["    " + h for h in header]
    repl, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("c"), optimizations="basic")
    for sym, sub in repl:
        lines.append(f"    {sym} = {printer.doprint(sub)}")
    entries = [printer.doprint(e) if not e.is_number else repr(float(e)) for e in reduced]
    lines.append(f"    A = ({', '.join(entries[:targets_count])},)")
    lines.append(f"    r = ({', '.join(entries[targets_count:])},)")
    lines.append("    return A, r")
    return "\n".join(lines)


def _solve_lines(k: int, nonzero: list[list[bool]]) -> list[str]:
    """Straight-line Gaussian elimination without pivoting of the KKT system a z = r held in
    scalars a{i}_{j}, r{i}, skipping structural zeros: valid for the mass/constraint matrix
    in its natural order (M positive definite, -B M^-1 B^T negative definite), as in
    `System._derivative_columns`. A pivot below PIVOT_TOL times the largest entry of its
    original row (singular to working precision) becomes NaN, so the row's result is NaN."""
    nz = [list(row) for row in nonzero]
    lines = []
    for i in range(k):
        terms = [f"abs(a{i}_{j})" for j in range(k) if nz[i][j]] or ["0.0"]
        lines.append(f"s{i} = " + (terms[0] if len(terms) == 1 else f"max({', '.join(terms)})"))
    for c in range(k):
        lines.append(f"a{c}_{c} = a{c}_{c} if abs(a{c}_{c}) > PIVOT_TOL * s{c} else math.nan")
        for i in range(c + 1, k):
            if not nz[i][c]:
                continue
            lines.append(f"f = a{i}_{c} / a{c}_{c}")
            for j in range(c + 1, k):
                if nz[c][j]:
                    lines.append(
                        f"a{i}_{j} = a{i}_{j} - f * a{c}_{j}"
                        if nz[i][j]
                        else f"a{i}_{j} = -f * a{c}_{j}"
                    )
                    nz[i][j] = True
            lines.append(f"r{i} = r{i} - f * r{c}")
    for c in range(k - 1, -1, -1):
        rest = "".join(f" - a{c}_{j} * z{j}" for j in range(c + 1, k) if nz[c][j])
        lines.append(f"z{c} = (r{c}{rest}) / a{c}_{c}")
    return lines


def _lanes(n: int, nu: int, kkt: sp.Matrix, rhs: sp.Matrix, header: list[str]) -> str:
    """`derivative_lanes(T, XS, U, p, D)`: D = dx/dt for rows held as columns (XS (2n, m),
    U (n_u, m), T (m,)), one straight-line body per row with no calls, so that LLVM
    evaluates several rows per instruction. The kernels' fixed-step integrators use it."""
    k = kkt.shape[0]
    printer = _LanePrinter({"fully_qualified_modules": True})
    nonzero = [[not (kkt[i, j].is_number and kkt[i, j] == 0) for j in range(k)] for i in range(k)]
    exprs = [kkt[i, j] for i in range(k) for j in range(k) if nonzero[i][j]] + list(rhs)
    names = [f"a{i}_{j}" for i in range(k) for j in range(k) if nonzero[i][j]]
    names += [f"r{i}" for i in range(k)]
    body = ["t = T[b]"]
    body += [f"q{i} = XS[{i}, b]" for i in range(n)] + [f"qd{i} = XS[{n + i}, b]" for i in range(n)]
    body += [f"u{j} = U[{j}, b]" for j in range(nu)]
    repl, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("c"), optimizations="basic")
    body += [f"{sym} = {printer.doprint(sub)}" for sym, sub in repl]
    body += [f"{name} = {printer.doprint(e)}" for name, e in zip(names, reduced)]
    body += [f"a{i}_{j} = 0.0" for i in range(k) for j in range(k) if not nonzero[i][j]]
    body += _solve_lines(k, nonzero)
    body += [f"D[{i}, b] = qd{i}" for i in range(n)] + [f"D[{n + i}, b] = z{i}" for i in range(n)]
    lines = [
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        "def derivative_lanes(T, XS, U, p, D):",
    ]
    lines += ["    " + h for h in header]
    lines.append("    for b in range(XS.shape[1]):")
    lines += ["        " + line for line in body]
    return "\n".join(lines)


def _plain_symbols(d: Derived):
    """Map dynamicsymbols, multipliers, inputs and parameters to generated names."""
    spec = d.spec
    q = list(spec.coordinates)
    n = len(q)
    subs = {}
    for i, qi in enumerate(q):
        subs[qi.diff(t, 2)] = sp.Symbol(f"qdd{i}")
    for i, qi in enumerate(q):
        subs[qi.diff(t)] = sp.Symbol(f"qd{i}")
    for i, qi in enumerate(q):
        subs[qi] = sp.Symbol(f"q{i}")
    plain = {t: sp.Symbol("t")}
    plain |= {lam: sp.Symbol(f"lam{r}") for r, lam in enumerate(d.multipliers)}
    plain |= {u: sp.Symbol(f"u{j}") for j, u in enumerate(spec.inputs)}
    plain |= {p: sp.Symbol(f"p{k}") for k, p in enumerate(spec.parameters)}

    def convert(expr):
        return sp.sympify(me.msubs(sp.sympify(expr), subs)).xreplace(plain)

    x = [sp.Symbol(f"q{i}") for i in range(n)] + [sp.Symbol(f"qd{i}") for i in range(n)]
    z = [sp.Symbol(f"qdd{i}") for i in range(n)] + [
        sp.Symbol(f"lam{r}") for r in range(len(d.multipliers))
    ]
    u = [sp.Symbol(f"u{j}") for j in range(len(spec.inputs))]
    return convert, x, z, u


def _function(name: str, args: str, targets: list[str], exprs: list, header: list[str]) -> str:
    """One njit kernel: unpack arguments, cse, assign each target."""
    printer = _Printer({"fully_qualified_modules": True})
    lines = ["", "", '@njit(cache=True, error_model="numpy")', f"def {name}({args}):"]
    lines += ["    " + h for h in header]
    if exprs:
        repl, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("c"), optimizations="basic")
        for sym, sub in repl:
            lines.append(f"    {sym} = {printer.doprint(sub)}")
        for target, e in zip(targets, reduced):
            lines.append(f"    {target} = {printer.doprint(e)}")
    lines.append("    return")
    return "\n".join(lines)


def generate(d: Derived, key: str) -> str:
    """The source text of the compiled module of `d`."""
    spec = d.spec
    convert, x, z, u = _plain_symbols(d)
    n, m, nu = len(spec.coordinates), len(d.multipliers), len(spec.inputs)
    K = n + m

    unpack_x = [f"q{i} = x[{i}]" for i in range(n)] + [f"qd{i} = x[{n + i}]" for i in range(n)]
    unpack_u = [f"u{j} = u[{j}]" for j in range(nu)]
    unpack_p = [f"p{k} = p[{k}]" for k in range(len(spec.parameters))]
    unpack_z = [f"qdd{i} = z[{i}]" for i in range(n)] + [f"lam{r} = z[{n + r}]" for r in range(m)]

    M = d.mass.applyfunc(convert)
    B = d.constraint_matrix.applyfunc(convert)
    F = d.forcing.applyfunc(convert)
    gamma = d.constraint_accel.applyfunc(convert)
    kkt = sp.zeros(K, K)
    kkt[:n, :n] = M
    if m:
        kkt[:n, n:] = B.T
        kkt[n:, :n] = B
    rhs = sp.Matrix.vstack(F, gamma) if m else F
    matrix_targets = [f"A[{i}, {j}]" for i in range(K) for j in range(K)]
    matrix_exprs = [kkt[i, j] for i in range(K) for j in range(K)]
    rhs_targets = [f"r[{i}]" for i in range(K)]

    # residual R(x, u, z) = kkt(x) z - rhs(x, u): its Jacobians give exact linearisations
    R = kkt * sp.Matrix(z) - rhs
    Jx, Ju = R.jacobian(x), R.jacobian(u) if nu else sp.zeros(K, 0)

    residual = (
        (B * sp.Matrix(x[n:]) + d.constraint_bias.applyfunc(convert)) if m else sp.zeros(0, 1)
    )
    outputs = [convert(e) for e in d.outputs.values()]

    head = [
        f'"""Generated by lagrange-gym from {spec.name!r}. Do not edit; delete to rebuild."""',
        "import math  # noqa: F401",
        "",
        "import numpy",
        "import numpy as np",
        "from numba import njit, prange  # noqa: F401",
        "",
        f"KEY = {key!r}",
        f"NAME = {spec.name!r}",
        f"COORDINATES = {tuple(str(c.name) for c in spec.coordinates)!r}",
        f"INPUTS = {tuple(str(s) for s in spec.inputs)!r}",
        f"PARAMETERS = {tuple(str(s) for s in spec.parameters)!r}",
        f"DEFAULTS = {tuple(float(p.default) for p in spec.parameters.values())!r}",
        f"UNITS = {tuple(p.unit for p in spec.parameters.values())!r}",
        f"POSITIVE = {tuple(bool(p.positive) for p in spec.parameters.values())!r}",
        f"OUTPUTS = {tuple(d.outputs)!r}",
        f"N_Q = {n}",
        f"N_U = {nu}",
        f"N_C = {m}",
        f"N_P = {len(spec.parameters)}",
        f"N_OUT = {len(outputs)}",
        f"K = {K}",
    ]
    x_args = unpack_x + unpack_p
    parts = [
        "\n".join(head),
        _function(
            "kkt",
            "t, x, u, p, A, r",
            matrix_targets + rhs_targets,
            matrix_exprs + list(rhs),
            x_args + unpack_u,
        ),
        _function("kkt_matrix", "t, x, p, A", matrix_targets, matrix_exprs, x_args),
        _function(
            "energy_terms",
            "t, x, p, out",
            ["out[0]", "out[1]"],
            [convert(d.kinetic), convert(d.potential)],
            x_args,
        ),
        _function(
            "residual", "t, x, p, out", [f"out[{r}]" for r in range(m)], list(residual), x_args
        ),
        _function(
            "power_out",
            "t, x, u, p, z, out",
            ["out[0]"],
            [convert(d.power)],
            x_args + unpack_u + unpack_z,
        ),
        _function(
            "outputs",
            "t, x, u, p, z, out",
            [f"out[{k}]" for k in range(len(outputs))],
            outputs,
            x_args + unpack_u + unpack_z,
        ),
        _function(
            "jacobians",
            "t, x, u, p, z, Jx, Ju",
            [f"Jx[{i}, {j}]" for i in range(K) for j in range(2 * n)]
            + [f"Ju[{i}, {j}]" for i in range(K) for j in range(nu)],
            [Jx[i, j] for i in range(K) for j in range(2 * n)]
            + [Ju[i, j] for i in range(K) for j in range(nu)],
            x_args + unpack_u + unpack_z,
        ),
    ]
    printer = _Printer({"fully_qualified_modules": True})
    conditions = [printer.doprint(convert(e)) for e in spec.conditions.values()]
    parts.append(
        "\n".join(
            [
                "",
                "",
                f"CONDITIONS = {tuple(spec.conditions)!r}",
                "",
                "",
                "def conditions(p):",
                '    """Values that must be > 0 for the parameters to describe a valid system."""',
                *["    " + h for h in unpack_p],
                f"    return ({''.join(c + ', ' for c in conditions)})",
            ]
        )
    )
    parts.append(_vectorized(len(matrix_exprs), matrix_exprs + list(rhs), x_args + unpack_u))
    parts.append(_lanes(n, nu, kkt, rhs, unpack_p))
    kernels = KERNELS.read_text().split("# --- template starts here ---", 1)[1]
    return "\n".join(parts) + "\n\n" + kernels.lstrip("\n")
