"""One compiled step per (model, task): the runtime's whole step in one numba call.

The runtime's step is a chain of compiled pieces (clip and scale the actions, integrate,
check divergence, the observation, the task's reward, success and failure, the results)
that each cost a Python call, argument unboxing and boxed results: for the single env,
more than the integration itself. Here the chain is written out as the source of one
numba function, in a generated module of the model cache, that calls each piece through
its machine code's address (dynamics.calls: compiled once for its argument types, not
linked and optimised again into every task's and form's step); the runtime's arrays are
views of a few flat buffers, so the call takes ten arguments whatever the task.

numba caches that function's machine code on disk but keys it only on its own source,
not on the functions it calls. So the module's name hashes the source of everything it
reaches: the model module's key, the runtime's kernels, and the task's functions with
every function, constant and closure they reach in turn (`fingerprint`). A task whose
functions reach something that cannot be fingerprinted, or that numba cannot compile,
keeps the step of separate calls (the same results bit for bit).
"""

from __future__ import annotations

import hashlib
import re
import types
from pathlib import Path

import numpy as np

from dynamics import cache, calls

from . import buffers

_CODE_KEY = hashlib.sha256(
    b"".join(Path(m.__file__).read_bytes() for m in (buffers, calls))
).hexdigest()
"""The code of envs.buffers and dynamics.calls (the intrinsics and overloads the step's machine
code inlines), in the step's key."""
LIBRARIES = ("numpy", "numba", "math", "cmath", "builtins")
"""Top-level packages whose functions are identified by name (their code changes with
their version, which numba's cache already keys on), not hashed."""


def fingerprint(*objs) -> str | None:
    """sha256 of the code of `objs` and of everything it reaches (functions, numba
    dispatchers, closures, defaults, module attributes it names, constants), or None if it
    reaches an object whose content cannot be hashed."""
    h = hashlib.sha256()
    seen: set[int] = set()
    for obj in objs:
        if not _feed(h, obj, seen):
            return None
    return h.hexdigest()


def _names(code: types.CodeType):
    yield from code.co_names
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            yield from _names(const)


def _feed_code(h, code: types.CodeType) -> None:
    h.update(code.co_code)
    h.update(repr(code.co_names).encode())
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            _feed_code(h, const)
        else:
            h.update(repr((type(const).__name__, const)).encode())


def _cell(cell):
    try:
        return cell.cell_contents
    except ValueError:  # not assigned yet (a nested function referring to itself)
        return "<empty cell>"


def _library(obj) -> bool:
    module = getattr(obj, "__module__", None) or ""
    return module.partition(".")[0] in LIBRARIES


def _feed(h, obj, seen: set[int]) -> bool:
    obj = getattr(obj, "py_func", obj)  # a numba dispatcher: its Python function
    if isinstance(obj, (bool, int, float, complex, str, bytes, type(None), np.generic)):
        h.update(repr((type(obj).__name__, obj)).encode())
        return True
    if isinstance(obj, (tuple, list, frozenset)):
        h.update(f"{type(obj).__name__}{len(obj)}".encode())
        return all(_feed(h, v, seen) for v in obj)
    if isinstance(obj, np.ndarray):
        h.update(f"{obj.dtype}{obj.shape}".encode())
        h.update(np.ascontiguousarray(obj).tobytes())
        return True
    if isinstance(obj, types.ModuleType):
        h.update(f"module {obj.__name__}".encode())
        return True
    if isinstance(obj, (type, types.BuiltinFunctionType, np.ufunc)) or (
        callable(obj) and _library(obj)
    ):
        h.update(f"{getattr(obj, '__module__', '')}.{getattr(obj, '__qualname__', obj)}".encode())
        return True
    if not isinstance(obj, types.FunctionType):
        return False
    h.update(f"function {obj.__module__}.{obj.__qualname__}".encode())
    if id(obj) in seen:
        return True
    seen.add(id(obj))
    _feed_code(h, obj.__code__)
    cells = tuple(_cell(c) for c in obj.__closure__ or ())
    if not all(_feed(h, v, seen) for v in (obj.__defaults__ or ()) + cells):
        return False
    g = obj.__globals__
    names = set(_names(obj.__code__))
    for name in sorted(names):
        if name not in g:
            continue
        value = g[name]
        h.update(f"global {name}".encode())
        if not _feed(h, value, seen):
            return False
        if isinstance(value, types.ModuleType):  # module.attr: the attributes it names
            for attr in sorted(names):
                member = getattr(value, attr, None)
                if isinstance(member, types.FunctionType) or hasattr(member, "py_func"):
                    h.update(f"{name}.{attr}".encode())
                    if not _feed(h, member, seen):
                        return False
    return True


# ---- the generated step ----------------------------------------------------------------
RENAMED = {"Q": "terms"}
"""Runtime arrays named otherwise in the generated step: `Q` is the reward terms (in the
book Q is the generalised forces)."""


def _segment(lines: list[str], name: str, buf: str, start: int, width: int | None) -> None:
    """`name` = rows start.. of the flat buffer `buf` (width None: a column per row)."""
    name = RENAMED.get(name, name)
    if width is None:
        lines.append(f"    {name} = {buf}[n * {start}:n * {start + 1}]")
    else:
        lines.append(f"    {name} = matrix({buf}, n * {start}, n, {width})")


def source(plan: dict) -> str:
    """The generated module's text for a runtime's `plan` (see `envs.step.Step._plan`)."""
    body = _body(plan)
    head = _header(plan)
    _unpack(head, plan, set(re.findall(r"[A-Za-z_]\w*", "\n".join(body))))
    return "\n".join(head + body)


def _header(plan: dict) -> list[str]:
    """The module's imports, the step's signature and the check of its buffers' sizes."""
    lines = [
        "from numba import njit",
        "",
        "from dynamics.calls import call as _call",
        "from envs.buffers import column, matrix, put_column, put_rows",
        "",
        "# Every kernel is called through its address (dynamics.calls), from K_'s",
        "# `addresses`: the integrator (dynamics.stepping) and _outputs (dynamics.rows), which",
        "# read the model's kernels from `model_kernels`, the runtime's _apply, _advance,",
        "# _observe and _finish, the task's _term_k, _success, _failure and _derived_k. The",
        "# module's name hashes all of their code (envs.fused.build).",
        "",
        "",
        "@njit(cache=True, error_model='numpy')",
        "def step(actions, F_, B_, steps, O, C_, K_, model_params, task_params, horizon):",
        '    """One control period of every row; -1 (nothing changed) for a NaN or inf',
        "    action, else 1 if some row diverged, 0 if none did. model_params: the model's",
        "    parameters (one vector, or a row per copy), task_params: the record the task's",
        '    functions read."""',
        "    n = actions.shape[0]",
    ]
    if plan.get("perturbed"):  # envs.perturb: two more arguments
        lines[-6:-1] = [
            "def step(actions, F_, B_, steps, O, C_, K_, model_params, task_params, horizon,",
            "         applied, W):",
            '    """One control period of every row; -1 (nothing changed) for a NaN or inf',
            "    action, else 1 if some row diverged, 0 if none did. The inputs `applied`",
            "    (N, n_a) replace the commanded ones; with pushes, the generalised forces W",
            "    (N, n_q) are added to the forcing (model_params: each row's parameters;",
            '    task_params: the record the task\'s functions read)."""',
        ]
    f, b, c, k = plan["sizes"]  # of the buffers, which the unchecked views rely on
    return lines + [
        f"    if (F_.shape[0] != n * {f} or B_.shape[0] != n * {b} or C_.shape[0] != {c}",
        f"            or K_.shape[0] != {k}):",
        "        raise ValueError('the buffers do not have the sizes the step was made for')",
    ]


def _body(plan: dict) -> list[str]:
    """The step's work, after its views of the buffers: apply the actions, integrate,
    check divergence, the outputs, the task's functions and the results."""
    lines = [
        "    for k in range(addresses.shape[0]):  # written by envs.step.Step._install",
        "        if addresses[k] == 0:",
        "            raise RuntimeError('the fused step was called before it was bound')",
    ]
    if plan.get("rows"):  # each row's own parameters: the kernels take the first row's too
        lines += ["    one_params = model_params[0]", "    row_params = model_params"]
    else:
        lines += ["    one_params = model_params", "    row_params = None"]
    lines += [f"    if not {_invoke(plan, '_apply')}:", "        return -1"]
    if plan.get("perturbed"):
        lines += [
            "    for b in range(n):",
            "        for j in range(actuated.shape[0]):",
            "            U[b, actuated[j]] = applied[b, j]",
        ]
    lines += _integrate_lines(plan)
    lines.append(f"    any_diverged = {_invoke(plan, '_advance')}")
    if plan["outputs"]:
        lines += [
            f"    {_invoke(plan, '_outputs')}",
            "    for b in range(n):",
            f"        for i in range({plan['n_x']}):",
            "            rows_x[b, i] = X[b, i]",
            f"        for j in range({len(plan['outputs'])}):",
            f"            rows_x[b, {plan['n_x']} + j] = Y[b, output_index[j]]",
            "    x = rows_x",
        ]
    else:
        lines.append("    x = X")
    lines += _task_lines(plan)
    lines += [f"    bad = {_invoke(plan, '_finish')}", "    return 1 if any_diverged or bad else 0"]
    return lines + [""]


ARGUMENTS = {
    "_apply": "actions, input_mid, input_half, actuated, A, U",
    "_advance": "X, X_next, limits, diverged, T, dt, steps, horizon, steps_left",
    "_outputs": "T, X, U, one_params, row_params, Y, model_kernels",
    "_observe": "x, G, ops, obs_low, obs_high, obs64",
    "_finish": "terms, term_low, term_high, failed, diverged, steps_left, lowest, R, "
    "terminated, success, obs64, obs_low, O",
}
"""The arguments of each kernel the step calls; the task's functions take `TASK_ARGUMENTS`."""
TASK_ARGUMENTS = "xs, as_, gs, task_params"


def arguments(role: str) -> list[str]:
    """The step's variables that kernel `role` is called with."""
    return ARGUMENTS.get(role, TASK_ARGUMENTS).split(", ")


def _invoke(plan: dict, role: str, args: str | None = None) -> str:
    """The call of kernel `role` through its address (plan["calls"]: role -> (slot, label))."""
    slot, name = plan["calls"][role]
    args = ", ".join(arguments(role)) if args is None else args
    return f"_call(addresses[{slot}], {name!r}, ({args},))"


def _integrate_lines(plan: dict) -> list[str]:
    """The lines that advance every row one control period with the model's integrator:
    parameters one vector for every row, or each row's own (then the first row's gives the
    kernels the vector's shape); pushes add the generalised forces W."""
    if plan.get("row_by_row"):  # what erk_rows does for so few rows, without compiling it
        one = "model_params[r]" if plan.get("rows") else "model_params"
        args = f"T, X, U, {one}, h, substeps, ta, tw, tc, X_next, r, model_kernels"
        return [
            "    for r in range(n):  # the integrator's erk_row, one row at a time",
            f"        {_invoke(plan, 'integrator', args)}",
        ]
    forces = "W" if plan.get("pushed") else "None"
    args = (
        f"T, X, U, one_params, row_params, {forces}, h, substeps, ta, tw, tc, X_next, lo, "
        "min(n, lo + block), model_kernels"
    )
    return [
        "    for lo in range(0, n, block):  # the integrator's erk_rows, a block at a time",
        f"        {_invoke(plan, 'integrator', args)}",
    ]


def _unpack(lines: list[str], plan: dict, used: set[str]) -> None:
    """Append the lines that name the runtime's arrays and constants as views of the flat
    buffers F_ (floats), B_ (booleans), C_ (real constants) and K_ (integer constants), of
    those the step `used` (each view costs the step's compilation some code)."""
    for name, start, width in plan["floats"]:
        if RENAMED.get(name, name) in used:
            _segment(lines, name, "F_", start, width)
    for name, start in plan["bools"]:
        if name in used:
            _segment(lines, name, "B_", start, None)
    for name, start, length, shape in plan["constants"]:
        if name not in used:
            continue
        buf = "K_" if name in plan["integer_constants"] else "C_"
        if shape is None:
            lines.append(f"    {name} = {buf}[{start}]")
        elif len(shape) == 2:
            lines.append(f"    {name} = matrix({buf}, {start}, {shape[0]}, {shape[1]})")
        else:
            lines.append(f"    {name} = {buf}[{start}:{start + length}]")


def _task_lines(plan: dict) -> list[str]:
    """The generated step's calls of the task's functions, which read their inputs by name
    (envs.names): observation, reward terms, success and failure."""
    lines = [f"    # named inputs: {', '.join(plan['types'])}"]
    for var, cls, src, width in zip(
        ("xs", "as_", "gs"), ("_Rows", "_Actions", "_Goal"), ("x", "A", "G"), plan["widths"]
    ):
        cols = ", ".join(f"column({src}, {i})" for i in range(width))
        lines.append(f"    {var} = {cls}({cols})")
    lines.append(f"    {_invoke(plan, '_observe')}")
    for k, col in enumerate(plan["derived"]):
        lines.append(f"    put_column(obs64, {col}, {_invoke(plan, f'_derived_{k}')})")
    if plan["derived"]:
        lines += [
            "    for b in range(n):",
            f"        for j in range({plan['n_obs']}):",
            "            obs64[b, j] = min(max(obs64[b, j], obs_low[j]), obs_high[j])",
        ]
    for k in range(plan["n_terms"]):
        lines.append(f"    put_column(terms, {k}, {_invoke(plan, f'_term_{k}')})")
    lines.append(f"    put_rows(success, {_invoke(plan, '_success')})")
    if plan["failure"]:
        lines.append(f"    put_rows(failed, {_invoke(plan, '_failure')})")
    return lines


def build(plan: dict, functions: dict, types: dict | None = None):
    """The compiled step for `plan`, which calls `functions` (name -> numba dispatcher)
    through their addresses and whose globals are `types` (the named inputs' namedtuple
    classes, named in the source by their field hash), or None when the functions cannot
    be fingerprinted."""
    digest = fingerprint(*(functions[k] for k in sorted(functions)))
    if digest is None:
        return None
    body = source(plan)
    text = f"{plan['model_key']} {digest} {_CODE_KEY}\n{body}"
    key = hashlib.sha256(text.encode()).hexdigest()
    module = cache.load("step", key, f"KEY = {key!r}\n{body}")
    module.__dict__.update(types or {})
    return module.step
