"""The fixed-step Runge-Kutta integrator of every model, compiled once per machine (and the
derivative of many rows in vector lanes).

It calls the model's derivative (and its projection onto the velocity constraints) through
their addresses (`dynamics.calls`), read from the model's `table`, instead of linking them:
numba then compiles it once, into its cache beside this file, rather than once per model,
and a new model's first step compiles only the model's own derivative (measured here, CPU:
the arm's first single step 1.7 -> 0.7 s, the disk's vector lanes 2.0 s -> 0 once any
model has compiled them). Every kernel gives the results the model's own compiled copy gave,
bit for bit: the same operations in the same order, only not inlined. The call costs a
single row's step 0.1-0.4 us (the arm's 16 derivative evaluations: 2.9 -> 3.3 us); rows in
vector lanes pay nothing measurable.

Rows are float64 and contiguous (T (N,), X (N, 2n), U (N, n_u), out like X); the
parameters p (n_p,) are one vector for every row, or P (N, n_p) each row's own (then p is
P's first row, for its shape); W (N, n_q), where not None, are generalised forces added to
each row's forcing (external pushes). numba prunes the branches on `P is None` and
`W is None` before compiling, so each form compiles only what it calls.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange
from numba.core import types

from . import calls

_f8 = types.float64
_V, _M = types.Array(_f8, 1, "C"), types.Array(_f8, 2, "C")  # a vector, a matrix
SIGNATURES = {
    "derivative_lanes": (_V, _M, _M, _V, _M),  # (T, XS, U, p, D)
    "derivative_lanes_p": (_V, _M, _M, _M, _M),  # (T, XS, U, P, D)
    "derivative_lanes_w": (_V, _M, _M, _M, _M, _M),  # (T, XS, U, P, W, D)
    "project": (_f8, _V, _V, _M, _V),  # (t, x, p, A, z)
    "energy_terms": (_f8, _V, _V, _V),  # (t, x, p, out)
    "residual": (_f8, _V, _V, _V),  # (t, x, p, out)
    "accelerations": (_f8, _V, _V, _V, _M, _V),  # (t, x, u, p, A, z)
    "power_out": (_f8, _V, _V, _V, _V, _V),  # (t, x, u, p, z, out)
    "outputs": (_f8, _V, _V, _V, _V, _V),  # (t, x, u, p, z, out)
}
"""The argument types every model's kernel is called with here and in `dynamics.rows`
(see codegen and kernels)."""
(
    DERIVATIVE,
    DERIVATIVE_P,
    DERIVATIVE_W,
    PROJECT,
    ENERGY,
    RESIDUAL,
    ACCELERATIONS,
    POWER,
    OUTPUTS,
) = (f"({calls.text(s)})" for s in SIGNATURES.values())
"""The labels of those calls (the kernels return nothing)."""
(
    AT_DERIVATIVE,
    AT_DERIVATIVE_P,
    AT_DERIVATIVE_W,
    AT_PROJECT,
    AT_ENERGY,
    AT_RESIDUAL,
    AT_ACCELERATIONS,
    AT_POWER,
    AT_OUTPUTS,
    N_Q,
    N_C,
    K,
) = range(len(SIGNATURES) + 3)
"""Where a model's table holds the addresses of its kernels, then its sizes."""
TABLE_SIZE = K + 1

LANES_FROM = 8
"""Fewer rows step one row at a time (`erk_row`, called by System and the envs): the column
loops' set-up per stage costs more than the arithmetic of a few rows (the single env:
150 ns against 20 ns per derivative evaluation)."""

_SLOTS = {name: slot for slot, name in enumerate(SIGNATURES)}


def table(module, *kernels: str) -> np.ndarray:
    """The int64 table the model-independent kernels read model `module` from: the
    addresses of its `kernels` (names of SIGNATURES; `project` too when the model has
    constraints), each compiled or loaded for its signature on first request, then n_q, n_c
    and K. One table a module, kept on the module (`_ADDRESSES`) for as long as it lives:
    an address is of code the module holds. A fraction of a microsecond once filled (the
    envs call it at every step)."""
    try:
        t, filled = module._ADDRESSES
    except AttributeError:
        t, filled = np.zeros(TABLE_SIZE, np.int64), set()
        t[N_Q], t[N_C], t[K] = module.N_Q, module.N_C, module.K
        if module.N_C:
            _fill(module, t, filled, "project")
        module._ADDRESSES = t, filled
    if not filled.issuperset(kernels):
        for name in kernels:
            _fill(module, t, filled, name)
    return t


def _fill(module, t: np.ndarray, filled: set, name: str) -> None:
    if name not in filled:
        t[_SLOTS[name]] = calls.address(getattr(module, name), SIGNATURES[name])
        filled.add(name)


def lane_kernels(per_row: bool, pushed: bool) -> tuple[str, ...]:
    """The derivative `erk_rows` calls for rows with their own parameters or pushes;
    `erk_row` always calls `derivative_lanes`."""
    return (
        "derivative_lanes_w" if pushed else "derivative_lanes_p" if per_row else "derivative_lanes",
    )


@njit(cache=True, error_model="numpy")
def erk_rows(T, X, U, p, P, W, h, substeps, a, w, c, out, lo, hi, model):
    """Rows lo..hi of X advanced by `substeps` explicit Runge-Kutta steps of size h with the
    tableau (a, w, c), inputs held, into out; `model`: the model's `table`. The rows are
    copied into columns so that the model's derivative evaluates them in vector lanes, and
    each row's arithmetic is the same whatever rows share its block (results do not depend
    on blocking or threads). Constrained models are projected onto their velocity
    constraints after every step. A row with parameters P[r] steps bit for bit as it would
    with p = P[r], and W = 0 as W None. Callers step fewer than LANES_FROM rows without
    pushes by `erk_row` (the same result, faster for so few)."""
    m = hi - lo
    pc = as_columns(P, p.shape[0], lo, m)  # the block's parameters
    wc = as_columns(W, model[N_Q], lo, m)  # the block's generalised forces
    x = as_columns(X, X.shape[1], lo, m)
    u = as_columns(U, U.shape[1], lo, m)
    t = np.empty(m)
    for b in range(m):
        t[b] = T[lo + b]
    xs = np.empty_like(x)  # a stage's state, and the step's weighted sum
    k = np.empty((w.shape[0],) + x.shape)  # the stages' derivatives
    ts = np.empty(m)  # a stage's times
    for _ in range(substeps):
        erk_step(t, x, u, p, pc, wc, P, W, h, a, w, c, xs, k, ts, model)
        if model[N_C]:
            project_columns(t, x, p, P, lo, model)
    for b in range(m):
        for i in range(x.shape[0]):
            out[lo + b, i] = x[i, b]


@njit(inline="always", error_model="numpy")
def as_columns(R, width, lo, m):
    """Rows lo..lo + m of R (N, width) as the columns of a new (width, m) array; a
    (width, 0) array where R is None (numba prunes the branch)."""
    if R is None:
        return np.empty((width, 0))
    cols = np.empty((width, m))
    for b in range(m):
        for i in range(width):
            cols[i, b] = R[lo + b, i]
    return cols


@njit(inline="always", error_model="numpy")
def erk_step(t, x, u, p, pc, wc, P, W, h, a, w, c, xs, k, ts, model):
    """One step of size h of the tableau (a, w, c) on the block's columns x (2n, m) at
    times t, in place: stage s's derivative k[s] at t + c_s h and x + h sum_j a_sj k[j],
    then x += h sum_s w_s k[s], t += h. xs, k and ts are work arrays; the parameters are
    chosen as in `lanes_derivative`."""
    for s in range(w.shape[0]):
        for b in range(ts.shape[0]):
            ts[b] = t[b] + c[s] * h
        if s == 0:
            lanes_derivative(ts, x, u, p, pc, wc, P, W, k[0], model)
            continue
        weighted_sum(x, k, a[s], s, h, xs, xs)
        lanes_derivative(ts, xs, u, p, pc, wc, P, W, k[s], model)
    weighted_sum(x, k, w, w.shape[0], h, xs, x)
    for b in range(t.shape[0]):
        t[b] += h


@njit(inline="always", error_model="numpy")
def weighted_sum(x, k, f, count, h, acc, dest):
    """dest <- x + h (sum over j < count of f_j k[j]), column by column, summed in acc
    first (dest may be acc or x); stages of weight zero are skipped."""
    for i in range(x.shape[0]):
        for b in range(x.shape[1]):
            acc[i, b] = 0.0
        for j in range(count):
            fj = f[j]
            if fj != 0.0:
                for b in range(x.shape[1]):
                    acc[i, b] += fj * k[j, i, b]
        for b in range(x.shape[1]):
            dest[i, b] = x[i, b] + h * acc[i, b]


@njit(inline="always", error_model="numpy")
def lanes_derivative(t, x, u, p, pc, wc, P, W, d, model):
    """d <- the derivative of the columns x: the model's `derivative_lanes` with p (P
    None), `derivative_lanes_p` with each column's own parameters pc, or
    `derivative_lanes_w` with the generalised forces wc too (W not None)."""
    if P is None:
        calls.call(model[AT_DERIVATIVE], DERIVATIVE, (t, x, u, p, d))
    elif W is None:
        calls.call(model[AT_DERIVATIVE_P], DERIVATIVE_P, (t, x, u, pc, d))
    else:
        calls.call(model[AT_DERIVATIVE_W], DERIVATIVE_W, (t, x, u, pc, wc, d))


@njit(cache=True, error_model="numpy")
def erk_row(T, X, U, p, h, substeps, a, w, c, out, r, model):
    """`erk_rows` for the one row r, with the same operations in the same order (so the
    same result bit for bit), without the loops over the block's columns."""
    n2 = X.shape[1]
    s_count = w.shape[0]
    x = np.empty((n2, 1))
    xs = np.empty((n2, 1))
    k = np.empty((s_count, n2, 1))
    u = np.empty((U.shape[1], 1))
    t = np.empty(1)
    ts = np.empty(1)
    t[0] = T[r]
    for i in range(n2):
        x[i, 0] = X[r, i]
    for j in range(U.shape[1]):
        u[j, 0] = U[r, j]
    for _ in range(substeps):
        for s in range(s_count):
            ts[0] = t[0] + c[s] * h
            if s == 0:
                calls.call(model[AT_DERIVATIVE], DERIVATIVE, (ts, x, u, p, k[0]))
                continue
            for i in range(n2):
                acc = 0.0
                for j in range(s):
                    f = a[s, j]
                    if f != 0.0:
                        acc += f * k[j, i, 0]
                xs[i, 0] = x[i, 0] + h * acc
            calls.call(model[AT_DERIVATIVE], DERIVATIVE, (ts, xs, u, p, k[s]))
        for i in range(n2):
            acc = 0.0
            for s in range(s_count):
                f = w[s]
                if f != 0.0:
                    acc += f * k[s, i, 0]
            x[i, 0] += h * acc
        t[0] += h
        if model[N_C]:
            project_columns(t, x, p, None, 0, model)
    for i in range(n2):
        out[r, i] = x[i, 0]


@njit(cache=True, error_model="numpy")
def project_columns(t, x, p, P, lo, model):
    """The model's `project` on every row held as a column of x (2n, m), with the
    parameters p (P None) or each column b's own P[lo + b]."""
    k, n_q = model[K], model[N_Q]
    A = np.empty((k, k + 1))  # a spare column for solve
    z = np.empty(k)
    row = np.empty(x.shape[0])
    for b in range(x.shape[1]):
        for i in range(x.shape[0]):
            row[i] = x[i, b]
        if P is None:
            calls.call(model[AT_PROJECT], PROJECT, (t[b], row, p, A, z))
        else:
            calls.call(model[AT_PROJECT], PROJECT, (t[b], row, P[lo + b], A, z))
        for i in range(n_q, x.shape[0]):
            x[i, b] = row[i]


@njit(cache=True, error_model="numpy")
def derivative_rows(T, X, U, p, out, block, model):
    """out <- the derivative of every row of X, `block` rows at a time copied into columns,
    so that the model's `derivative_lanes` evaluates several rows per instruction (large
    batches; the model's `derivative_batch` does a row at a time)."""
    n2, nu = X.shape[1], U.shape[1]
    for lo in range(0, X.shape[0], block):
        m = min(block, X.shape[0] - lo)
        t = np.empty(m)
        x = np.empty((n2, m))
        u = np.empty((nu, m))
        d = np.empty((n2, m))
        for b in range(m):
            t[b] = T[lo + b]
            for i in range(n2):
                x[i, b] = X[lo + b, i]
            for j in range(nu):
                u[j, b] = U[lo + b, j]
        calls.call(model[AT_DERIVATIVE], DERIVATIVE, (t, x, u, p, d))
        for b in range(m):
            for i in range(n2):
                out[lo + b, i] = d[i, b]


@njit(cache=True, error_model="numpy", parallel=True)
def erk_batch_parallel(T, X, U, p, P, h, substeps, a, w, c, out, block, model):
    """`erk_rows` over all rows (W None), `block` rows at a time, the blocks spread over
    numba's threads (numba.set_num_threads): bit for bit the same result."""
    n = X.shape[0]
    for j in prange((n + block - 1) // block):
        erk_rows(
            T,
            X,
            U,
            p,
            P,
            None,
            h,
            substeps,
            a,
            w,
            c,
            out,
            j * block,
            min(n, (j + 1) * block),
            model,
        )
