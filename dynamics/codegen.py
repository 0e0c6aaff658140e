"""Code generation: derived equations -> a Python module of numba kernels.

All of a model's expressions are reduced together by sympy's common-subexpression
elimination (`program.Program`) and each kernel prints, as straight-line scalar code (`math`
functions) that writes into output arrays, the assignments its own results need; the
linearisation's Jacobians are differentiated through the same assignments. The fixed
kernels in `kernels.py` (right-hand side, constraint projection, batched energy...) are
appended to the same module so that numba's on-disk cache can hold the whole model; the
functions they share with every model (the pivoting solve, the lanes' sin and cos,
finiteness scans) are imported from `lanes.py`, and the integrator (`stepping.py`) calls
the model's derivative through its address: both are compiled once per machine. See
benchmarks/dynamics.py for why numba and not numpy or C.
"""

from __future__ import annotations

from pathlib import Path

import sympy as sp
from sympy.printing.pycode import PythonCodePrinter

from .derive import Derived
from .program import Program
from .spec import inertia_matrix

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


def _solve_lines(k: int, nonzero: list[list[bool]]) -> list[str]:
    """Straight-line symmetric Gaussian elimination without pivoting (LDL^T order) of the
    KKT system a z = r held in scalars a{i}_{j} (upper triangle, j >= i) and r{i}, skipping
    structural zeros: valid for the mass/constraint matrix in its natural order, which is
    symmetric and stays so under elimination (M positive definite, then -B M^-1 B^T negative
    definite), so only the upper triangle is updated, half the work of a general
    elimination. A pivot below PIVOT_TOL times the largest entry of its original row
    (singular to working precision) becomes NaN, so the row's result is NaN."""
    nz = [list(row) for row in nonzero]

    def a(i, j):
        return f"a{min(i, j)}_{max(i, j)}"

    lines = []
    for i in range(k):
        terms = [f"abs({a(i, j)})" for j in range(k) if nz[i][j]] or ["0.0"]
        lines.append(f"s{i} = " + (terms[0] if len(terms) == 1 else f"max({', '.join(terms)})"))
    for c in range(k):
        lines.append(f"a{c}_{c} = a{c}_{c} if abs(a{c}_{c}) > PIVOT_TOL * s{c} else math.nan")
        for i in range(c + 1, k):
            if not nz[c][i]:
                continue
            lines.append(f"f = a{c}_{i} / a{c}_{c}")
            for j in range(i, k):
                if nz[c][j]:
                    lines.append(
                        f"a{i}_{j} = a{i}_{j} - f * a{c}_{j}"
                        if nz[i][j]
                        else f"a{i}_{j} = -f * a{c}_{j}"
                    )
                    nz[i][j] = nz[j][i] = True
            lines.append(f"r{i} = r{i} - f * r{c}")
    for c in range(k - 1, -1, -1):
        rest = "".join(f" - a{c}_{j} * z{j}" for j in range(c + 1, k) if nz[c][j])
        lines.append(f"z{c} = (r{c}{rest}) / a{c}_{c}")
    return lines


def _lanes(n: int, nu: int, prog: Program, n_p: int) -> str:
    """`derivative_lanes(T, XS, U, p, D)`: D = dx/dt for rows held as columns (XS (2n, m),
    U (n_u, m), T (m,)), one straight-line body per row with no calls, so that LLVM
    evaluates several rows per instruction. The kernels' fixed-step integrators use it.
    Two variants with the same body: `derivative_lanes_p(T, XS, U, P, D)` reads each
    column's own parameters from P (n_p, m), for copies stepped with their own parameter
    values, and `derivative_lanes_w(T, XS, U, P, W, D)` also adds the generalised forces W
    (n, m) to the forcing (external pushes; W = 0 gives the same results bit for bit)."""
    matrix, rhs = prog.results["kkt"], prog.results["rhs"]
    k = len(rhs)
    printer = _LanePrinter({"fully_qualified_modules": True})
    kkt = [[matrix[i * k + j] for j in range(k)] for i in range(k)]
    nonzero = [[not (kkt[i][j].is_number and kkt[i][j] == 0) for j in range(k)] for i in range(k)]
    upper = [(i, j) for i in range(k) for j in range(i, k)]  # the matrix is symmetric
    exprs = [kkt[i][j] for i, j in upper if nonzero[i][j]] + list(rhs)
    names = [f"a{i}_{j}" for i, j in upper if nonzero[i][j]]
    names += [f"r{i}" for i in range(k)]
    unpack = [f"q{i} = XS[{i}, b]" for i in range(n)] + [
        f"qd{i} = XS[{n + i}, b]" for i in range(n)
    ]
    unpack += [f"u{j} = U[{j}, b]" for j in range(nu)]
    unpack += [f"{sym} = {printer.doprint(sub)}" for sym, sub in prog.needed(exprs)]
    unpack += [f"{name} = {printer.doprint(e)}" for name, e in zip(names, exprs)]
    solve = [f"a{i}_{j} = 0.0" for i, j in upper if not nonzero[i][j]]
    solve += _solve_lines(k, nonzero)
    solve += [f"D[{i}, b] = qd{i}" for i in range(n)] + [f"D[{n + i}, b] = z{i}" for i in range(n)]
    per_row = [f"p{k} = P[{k}, b]" for k in range(n_p)]
    variants = [
        ("derivative_lanes(T, XS, U, p, D)", [f"p{k} = p[{k}]" for k in range(n_p)], [], []),
        ("derivative_lanes_p(T, XS, U, P, D)", [], per_row, []),
        (
            "derivative_lanes_w(T, XS, U, P, W, D)",
            [],
            per_row,
            [f"r{i} = r{i} + W[{i}, b]" for i in range(n)],
        ),
    ]
    text = []
    for signature, head, row_head, forces in variants:
        lines = ["", "", '@njit(cache=True, error_model="numpy")', f"def {signature}:"]
        lines += ["    " + line for line in head]
        lines.append("    for b in range(XS.shape[1]):")
        body = ["t = T[b]", *row_head, *unpack, *forces, *solve]
        lines += ["        " + line for line in body]
        text.append("\n".join(lines))
    return "\n".join(text)


def _points(d: Derived) -> str:
    """`point_forces(t, x, p, k, f, out)`: out = the generalised forces of the force f (its
    components in the basis of the point's velocity) at point k of the spec's `points`,
    from their own common subexpressions (the equations' code is left as it is)."""
    code = d.code
    n = len(code.x) // 2
    header = [f"q{i} = x[{i}]" for i in range(n)]
    header += [f"p{k} = p[{k}]" for k in range(len(code.p))]
    header += [f"f{j} = f[{j}]" for j in range(3)]
    printer = _Printer({"fully_qualified_modules": True})
    lines = [
        "",
        "",
        '@njit(cache=True, error_model="numpy")',
        "def point_forces(t, x, p, k, f, out):",
    ]
    lines += ["    " + h for h in header]
    for index, forces in enumerate(code.points.values()):
        prog = Program({"Q": forces}, prefix="e")
        lines.append(f"    {'if' if index == 0 else 'elif'} k == {index}:")
        lines += [f"        {sym} = {printer.doprint(sub)}" for sym, sub in prog.steps]
        lines += [
            f"        out[{i}] = {printer.doprint(e)}" for i, e in enumerate(prog.results["Q"])
        ]
    if not code.points:
        lines.append("    out[:] = math.nan")
    lines.append("    return")
    return "\n".join(lines)


def _plain_symbols(d: Derived):
    """(convert, x, z, u): a map from the spec's parameters and inputs to the generated
    names, and the plain state, acceleration/multiplier and input symbols of `d.code`."""
    spec, c = d.spec, d.code
    plain = dict(zip(spec.parameters, c.p)) | dict(zip(spec.inputs, c.u))

    def convert(expr):
        return sp.sympify(expr).xreplace(plain)

    return convert, list(c.x), list(c.z), list(c.u)


def _function(
    name: str, args: str, targets: list[str], exprs: list, header: list[str], steps: list
) -> str:
    """One njit kernel: unpack arguments, run `steps` [(symbol, expression)], assign each
    target its expression."""
    printer = _Printer({"fully_qualified_modules": True})
    lines = ["", "", '@njit(cache=True, error_model="numpy")', f"def {name}({args}):"]
    lines += ["    " + h for h in header]
    lines += [f"    {sym} = {printer.doprint(sub)}" for sym, sub in steps]
    lines += [f"    {target} = {printer.doprint(e)}" for target, e in zip(targets, exprs)]
    lines.append("    return")
    return "\n".join(lines)


def _bodies(spec, convert, unpack_p) -> str:
    """BODIES ((name, parameters read), ...) and `inertias(p)`: each body's inertia tensor
    as its 6 entries (xx, xy, xz, yy, yz, zz), checked by `dynamics.physical`."""
    printer = _Printer({"fully_qualified_modules": True})
    names, entries = [], []
    for name, inertia in spec.bodies.items():
        m = inertia_matrix(inertia)
        reads = sorted(str(s) for s in m.free_symbols)
        names.append((name, tuple(reads)))
        six = (m[0, 0], m[0, 1], m[0, 2], m[1, 1], m[1, 2], m[2, 2])
        entries.append("(" + ", ".join(printer.doprint(convert(sp.sympify(e))) for e in six) + ")")
    return "\n".join(
        [
            "",
            "",
            f"BODIES = {tuple(names)!r}",
            "",
            "",
            "def inertias(p):",
            '    """Each body\'s inertia tensor entries (xx, xy, xz, yy, yz, zz)."""',
            *["    " + h for h in unpack_p],
            f"    return ({''.join(e + ', ' for e in entries)})",
        ]
    )


def _unpacking(d: Derived) -> dict[str, list[str]]:
    """The lines that unpack a kernel's arguments into the generated names, by argument:
    x (q0.., qd0..), u (u0..), p (p0..) and z (qdd0.., lam0..)."""
    n, m, nu = len(d.spec.coordinates), len(d.multipliers), len(d.spec.inputs)
    return {
        "x": [f"q{i} = x[{i}]" for i in range(n)] + [f"qd{i} = x[{n + i}]" for i in range(n)],
        "u": [f"u{j} = u[{j}]" for j in range(nu)],
        "p": [f"p{k} = p[{k}]" for k in range(len(d.spec.parameters))],
        "z": [f"qdd{i} = z[{i}]" for i in range(n)] + [f"lam{r} = z[{n + r}]" for r in range(m)],
    }


def _program(d: Derived, x: list) -> Program:
    """One program of shared assignments for every expression the kernels evaluate: the
    KKT matrix [[M, B^T], [B, 0]] (K x K, row by row) and right-hand side [F; gamma] of the
    accelerations and multipliers, [T, V], the constraint residual B qdot + b, the power
    and the outputs."""
    code = d.code
    n, m = len(d.spec.coordinates), len(d.multipliers)
    K = n + m
    M, B, F, gamma = code.mass, code.constraint_matrix, code.forcing, code.constraint_accel
    kkt = sp.zeros(K, K)
    kkt[:n, :n] = M
    if m:
        kkt[:n, n:] = B.T
        kkt[n:, :n] = B
    rhs = sp.Matrix.vstack(F, gamma) if m else F
    residual = (B * sp.Matrix(x[n:]) + code.constraint_bias) if m else sp.zeros(0, 1)
    return Program(
        {
            "kkt": [kkt[i, j] for i in range(K) for j in range(K)],
            "rhs": list(rhs),
            "energy": [code.kinetic, code.potential],
            "residual": list(residual),
            "power": [code.power],
            "outputs": list(code.outputs.values()),
        }
    )


def _linearisation(prog: Program, x: list, z: list, u: list, n: int) -> tuple[list, list]:
    """(steps, exprs): the assignments and the entries of Jx = dR/dx (K x 2n, row by row)
    then Ju = dR/du (K x n_u) of the residual R(x, u, z) = kkt(x) z - rhs(x, u), whose
    Jacobians give exact linearisations."""
    res = prog.results
    K, nu = len(res["rhs"]), len(u)
    R = [
        sp.Add(*[res["kkt"][i * K + j] * z[j] for j in range(K)]) - res["rhs"][i] for i in range(K)
    ]
    steps, J = prog.derivatives(R, list(x) + list(u))
    exprs = [J[i][j] for i in range(K) for j in range(2 * n)]
    exprs += [J[i][2 * n + j] for i in range(K) for j in range(nu)]
    return steps, exprs


def _constants(d: Derived, key: str) -> str:
    """The module's docstring, imports and constants (names, defaults, sizes)."""
    spec, code = d.spec, d.code
    n, m, nu = len(spec.coordinates), len(d.multipliers), len(spec.inputs)
    params = spec.parameters.values()
    return "\n".join(
        [
            f'"""Generated by lagrange-gym from {spec.name!r}. Do not edit; delete to rebuild."""',
            "import math  # noqa: F401",
            "",
            "import numpy",
            "import numpy as np",
            "from numba import njit  # noqa: F401",
            "",
            "from dynamics.lanes import (  # noqa: F401",
            "    PIVOT_TOL, all_finite, fail, first_nonfinite, solve, vcos, vsin,",
            ")",
            "",
            f"KEY = {key!r}",
            f"NAME = {spec.name!r}",
            f"COORDINATES = {tuple(str(c.name) for c in spec.coordinates)!r}",
            f"INPUTS = {tuple(str(s) for s in spec.inputs)!r}",
            f"PARAMETERS = {tuple(str(s) for s in spec.parameters)!r}",
            f"DEFAULTS = {tuple(float(p.default) for p in params)!r}",
            f"UNITS = {tuple(p.unit for p in params)!r}",
            f"POSITIVE = {tuple(bool(p.positive) for p in params)!r}",
            f"NONNEGATIVE = {tuple(bool(p.nonnegative) for p in params)!r}",
            f"OUTPUTS = {tuple(code.outputs)!r}",
            f"N_Q = {n}",
            f"N_U = {nu}",
            f"N_C = {m}",
            f"N_P = {len(spec.parameters)}",
            f"N_OUT = {len(code.outputs)}",
            f"K = {n + m}",
            f"POINTS = {tuple(str(k) for k in spec.points)!r}",
            f"POINT_DIMS = {tuple(len(v) for v in spec.points.values())!r}",
        ]
    )


def _kernels(d: Derived, prog: Program, x: list, z: list, u: list) -> list[str]:
    """The model's own kernels, each printing only the assignments its results need:
    `kkt`, `kkt_matrix`, `energy_terms`, `residual`, `power_out`, `outputs`, `jacobians`."""
    n, m, nu = len(d.spec.coordinates), len(d.multipliers), len(d.spec.inputs)
    K = n + m
    res = prog.results
    unpack = _unpacking(d)
    x_args = unpack["x"] + unpack["p"]
    x_zu = x_args + unpack["u"] + unpack["z"]
    matrix_targets = [f"A[{i}, {j}]" for i in range(K) for j in range(K)]
    jac_steps, jac_exprs = _linearisation(prog, x, z, u, n)

    def kernel(name, args, targets, exprs, header, extra=()):
        extra = list(extra)
        steps = prog.needed(list(exprs) + [e for _, e in extra])
        return _function(name, args, targets, exprs, header, steps + extra)

    return [
        kernel(
            "kkt",
            "t, x, u, p, A, r",
            matrix_targets + [f"r[{i}]" for i in range(K)],
            res["kkt"] + res["rhs"],
            x_args + unpack["u"],
        ),
        kernel("kkt_matrix", "t, x, p, A", matrix_targets, res["kkt"], x_args),
        kernel("energy_terms", "t, x, p, out", ["out[0]", "out[1]"], res["energy"], x_args),
        kernel(
            "residual", "t, x, p, out", [f"out[{r}]" for r in range(m)], res["residual"], x_args
        ),
        kernel("power_out", "t, x, u, p, z, out", ["out[0]"], res["power"], x_zu),
        kernel(
            "outputs",
            "t, x, u, p, z, out",
            [f"out[{k}]" for k in range(len(d.code.outputs))],
            res["outputs"],
            x_zu,
        ),
        kernel(
            "jacobians",
            "t, x, u, p, z, Jx, Ju",
            [f"Jx[{i}, {j}]" for i in range(K) for j in range(2 * n)]
            + [f"Ju[{i}, {j}]" for i in range(K) for j in range(nu)],
            jac_exprs,
            x_zu,
            jac_steps,
        ),
    ]


def _conditions(spec, convert, unpack_p) -> str:
    """CONDITIONS (their names) and `conditions(p)`: the values that must be > 0."""
    printer = _Printer({"fully_qualified_modules": True})
    conditions = [printer.doprint(convert(e)) for e in spec.conditions.values()]
    return "\n".join(
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


def generate(d: Derived, key: str) -> str:
    """The source text of the compiled module of `d`: its constants, the kernels printed
    from one program of shared assignments, the parameters' conditions and bodies, the
    derivative over rows in vector lanes, the point forces, then the model-independent
    kernels of `kernels.py`."""
    spec = d.spec
    convert, x, z, u = _plain_symbols(d)
    prog = _program(d, x)
    unpack_p = _unpacking(d)["p"]
    parts = [
        _constants(d, key),
        *_kernels(d, prog, x, z, u),
        _conditions(spec, convert, unpack_p),
        _bodies(spec, convert, unpack_p),
        _lanes(len(spec.coordinates), len(spec.inputs), prog, len(spec.parameters)),
        _points(d),
    ]
    kernels = KERNELS.read_text().split("# --- template starts here ---", 1)[1]
    return "\n".join(parts) + "\n\n" + kernels.lstrip("\n")
