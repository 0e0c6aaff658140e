"""Model-independent numba kernels, appended to every generated model module.

They call the generated `kkt`, `kkt_matrix`, `residual`, `energy_terms`, `power_out`,
`outputs` and read the constants N_Q, N_C, K, N_OUT of that module, so this file is a
template and is never imported by itself; what they share with every model (`solve`,
`vsin`, ...) is imported from `lanes.py`, compiled once per machine. One kernel serves
the shared parameters and each row's own: `P` None or an array (numba prunes the other
branch before compiling), so a form compiles only what it calls, when first called. Everything is batched over a leading axis and
allocates its work arrays once per call. No kernel raises on bad values (division by zero
follows numpy's rules): a row whose result is undefined comes back NaN, for the caller to see.
"""

# ruff: noqa: F821, E501
# --- template starts here ---
import llvmlite.binding  # noqa: E402

# LLVM vectorises a loop whose arrays might overlap only after checking at run time that they
# do not, and gives up beyond 128 such checks: `derivative_lanes` reads 2n + n_u + 1 rows and
# writes 2n, past that from four coordinates on (a chain of four links on a cart: 8.6e6
# evaluations/s unvectorised, 5.7e7 vectorised). The checks run once per block of rows.
llvmlite.binding.set_option("", "-vectorize-memory-check-threshold=10000")


@njit(cache=True, error_model="numpy")
def accelerations(t, x, u, p, A, z):
    """z <- [qddot, lambda] at (t, x, u)."""
    kkt(t, x, u, p, A, z)
    solve(A, z)


@njit(cache=True, error_model="numpy")
def rhs(t, x, u, p, A, z, dx):
    accelerations(t, x, u, p, A, z)
    for i in range(N_Q):
        dx[i] = x[N_Q + i]
        dx[N_Q + i] = z[i]


@njit(cache=True, error_model="numpy")
def project(t, x, p, A, z):
    """Remove the constraint violation B qdot + b from the rates, orthogonally in the
    kinetic-energy metric: qdot <- qdot + dv,
    `[[M, B^T], [B, 0]] [dv; mu] = [0; -(B qdot + b)]`."""
    if N_C == 0:
        return
    kkt_matrix(t, x, p, A)
    for i in range(N_Q):
        z[i] = 0.0
    residual(t, x, p, z[N_Q:])
    for r in range(N_C):
        z[N_Q + r] = -z[N_Q + r]
    solve(A, z)
    for i in range(N_Q):
        x[N_Q + i] += z[i]


@njit(cache=True, error_model="numpy")
def derivative_batch(T, X, U, p, out):
    A = np.empty((K, K + 1))  # a spare column for solve
    z = np.empty(K)
    for b in range(X.shape[0]):
        rhs(T[b], X[b], U[b], p, A, z, out[b])


@njit(cache=True, error_model="numpy")
def derivative_rows(T, X, U, p, out, block):
    """`derivative_batch` through `derivative_lanes`: `block` rows at a time copied into
    columns, so that LLVM evaluates several rows per instruction (large batches)."""
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
        derivative_lanes(t, x, u, p, d)
        for b in range(m):
            for i in range(n2):
                out[lo + b, i] = d[i, b]


@njit(cache=True, error_model="numpy")
def accelerations_batch(T, X, U, p, out):
    A = np.empty((K, K + 1))  # a spare column for solve
    for b in range(X.shape[0]):
        accelerations(T[b], X[b], U[b], p, A, out[b])


# ---- fixed-step Runge-Kutta over rows held in vector lanes ---------------------------------
@njit(cache=True, error_model="numpy")
def erk_rows(T, X, U, p, P, W, h, substeps, a, w, c, out, lo, hi):
    """Rows lo..hi of X advanced by `substeps` explicit Runge-Kutta steps of size h with the
    tableau (a, w, c), inputs held, into out: the rows are copied into columns so that
    `derivative_lanes` evaluates them in vector lanes, and each row's arithmetic is the
    same whatever rows share its block (results do not depend on blocking or threads).
    Constrained models are projected onto their velocity constraints after every step.

    The parameters are p for every row (P None), or row r's own P[r]: the same operations
    on the same values, so a row with parameters P[r] steps bit for bit as it would with
    p = P[r]. numba prunes the branches on `P is None` before compiling, so the shared form
    never compiles the per-row kernels (the bicycle's `derivative_lanes_p` alone takes 20 s).
    W (N, n_q), where not None (with P), are generalised forces added to each row's forcing
    and held over the step (external pushes; W = 0 steps bit for bit as W None). Callers
    step fewer than LANES_FROM rows without pushes by `erk_row` (the same result, faster
    for so few): calling it from here would link it into every form of this kernel, whose
    compilation re-optimised it each time."""
    m = hi - lo
    pc = as_columns(P, p.shape[0], lo, m)  # the block's parameters
    wc = as_columns(W, N_Q, lo, m)  # the block's generalised forces
    x = as_columns(X, X.shape[1], lo, m)
    u = as_columns(U, U.shape[1], lo, m)
    t = np.empty(m)
    for b in range(m):
        t[b] = T[lo + b]
    xs = np.empty_like(x)  # a stage's state, and the step's weighted sum
    k = np.empty((w.shape[0],) + x.shape)  # the stages' derivatives
    ts = np.empty(m)  # a stage's times
    for _ in range(substeps):
        erk_step(t, x, u, p, pc, wc, P, W, h, a, w, c, xs, k, ts)
        if N_C:
            project_columns(t, x, p, P, lo)
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
def erk_step(t, x, u, p, pc, wc, P, W, h, a, w, c, xs, k, ts):
    """One step of size h of the tableau (a, w, c) on the block's columns x (2n, m) at
    times t, in place: stage s's derivative k[s] at t + c_s h and x + h sum_j a_sj k[j],
    then x += h sum_s w_s k[s], t += h. xs, k and ts are work arrays; the parameters are
    chosen as in `lanes_derivative`."""
    for s in range(w.shape[0]):
        for b in range(ts.shape[0]):
            ts[b] = t[b] + c[s] * h
        if s == 0:
            lanes_derivative(ts, x, u, p, pc, wc, P, W, k[0])
            continue
        weighted_sum(x, k, a[s], s, h, xs, xs)
        lanes_derivative(ts, xs, u, p, pc, wc, P, W, k[s])
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
def lanes_derivative(t, x, u, p, pc, wc, P, W, d):
    """d <- the derivative of the columns x: `derivative_lanes` with p (P None),
    `derivative_lanes_p` with each column's own parameters pc, or `derivative_lanes_w`
    with the generalised forces wc too (W not None). numba prunes the other branches."""
    if P is None:
        derivative_lanes(t, x, u, p, d)
    elif W is None:
        derivative_lanes_p(t, x, u, pc, d)
    else:
        derivative_lanes_w(t, x, u, pc, wc, d)


LANES_FROM = 8
"""Fewer rows step one row at a time (`erk_row`, called by System and the envs): the column
loops' set-up per stage costs more than the arithmetic of a few rows (the single env:
150 ns against 20 ns per derivative evaluation)."""


@njit(cache=True, error_model="numpy")
def erk_row(T, X, U, p, h, substeps, a, w, c, out, r):
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
                derivative_lanes(ts, x, u, p, k[0])
                continue
            for i in range(n2):
                acc = 0.0
                for j in range(s):
                    f = a[s, j]
                    if f != 0.0:
                        acc += f * k[j, i, 0]
                xs[i, 0] = x[i, 0] + h * acc
            derivative_lanes(ts, xs, u, p, k[s])
        for i in range(n2):
            acc = 0.0
            for s in range(s_count):
                f = w[s]
                if f != 0.0:
                    acc += f * k[s, i, 0]
            x[i, 0] += h * acc
        t[0] += h
        if N_C:
            project_columns(t, x, p, None, 0)
    for i in range(n2):
        out[r, i] = x[i, 0]


@njit(cache=True, error_model="numpy")
def project_columns(t, x, p, P, lo):
    """`project` on every row held as a column of x (2n, m), with the parameters p (P
    None) or each column b's own P[lo + b] (numba prunes the branch, as in `erk_rows`)."""
    A = np.empty((K, K + 1))  # a spare column for solve
    z = np.empty(K)
    row = np.empty(x.shape[0])
    for b in range(x.shape[1]):
        for i in range(x.shape[0]):
            row[i] = x[i, b]
        if P is None:
            project(t[b], row, p, A, z)
        else:
            project(t[b], row, P[lo + b], A, z)
        for i in range(N_Q, x.shape[0]):
            x[i, b] = row[i]


@njit(cache=True, error_model="numpy", parallel=True)
def erk_batch_parallel(T, X, U, p, P, h, substeps, a, w, c, out, block):
    """The model's `erk_rows` over all rows (W None), `block` rows at a time, the blocks
    spread over numba's threads (numba.set_num_threads): bit for bit the same result."""
    n = X.shape[0]
    for j in prange((n + block - 1) // block):
        erk_rows(T, X, U, p, P, None, h, substeps, a, w, c, out, j * block,
                 min(n, (j + 1) * block))  # fmt: skip


@njit(cache=True, error_model="numpy")
def point_forces_batch(T, X, P, k, F, out):
    """out[b] = the generalised forces of the force F[b] at point k, row b's parameters
    P[b] (`point_forces`); F has the point's 2 or 3 components (padded with zeros)."""
    f = np.zeros(3)
    for b in range(X.shape[0]):
        for j in range(F.shape[1]):
            f[j] = F[b, j]
        point_forces(T[b], X[b], P[b], k, f, out[b])


@njit(cache=True, error_model="numpy")
def project_batch(T, X, p, out):
    A = np.empty((K, K + 1))  # a spare column for solve
    z = np.empty(K)
    for b in range(X.shape[0]):
        for i in range(X.shape[1]):
            out[b, i] = X[b, i]
        project(T[b], out[b], p, A, z)


@njit(cache=True, error_model="numpy")
def energy_batch(T, X, p, P, out):
    """[T, V] of every row, with the parameters p (P None) or each row's own P (N, n_p)."""
    for b in range(X.shape[0]):
        if P is None:
            energy_terms(T[b], X[b], p, out[b])
        else:
            energy_terms(T[b], X[b], P[b], out[b])


@njit(cache=True, error_model="numpy")
def residual_batch(T, X, p, P, out):
    """The constraint residual of every row, parameters as in `energy_batch`."""
    for b in range(X.shape[0]):
        if P is None:
            residual(T[b], X[b], p, out[b])
        else:
            residual(T[b], X[b], P[b], out[b])


@njit(cache=True, error_model="numpy")
def power_batch(T, X, U, p, out):
    A = np.empty((K, K + 1))  # a spare column for solve
    z = np.empty(K)
    for b in range(X.shape[0]):
        accelerations(T[b], X[b], U[b], p, A, z)
        power_out(T[b], X[b], U[b], p, z, out[b])


@njit(cache=True, error_model="numpy")
def outputs_batch(T, X, U, p, P, out):
    """The model's outputs of every row, parameters as in `energy_batch`."""
    A = np.empty((K, K + 1))  # a spare column for solve
    z = np.empty(K)
    for b in range(X.shape[0]):
        if P is None:
            accelerations(T[b], X[b], U[b], p, A, z)
            outputs(T[b], X[b], U[b], p, z, out[b])
        else:
            accelerations(T[b], X[b], U[b], P[b], A, z)
            outputs(T[b], X[b], U[b], P[b], z, out[b])


@njit(cache=True, error_model="numpy")
def linear_terms(t, x, u, p, A, z, Jx, Ju):
    """Fill z = [qddot, lambda], the matrix A = kkt(x), and Jx, Ju = dR/dx, dR/du of the
    residual R(x, u, z) = kkt(x) z - rhs(x, u), generated symbolically: then
    dz/dx = -A^-1 Jx and dz/du = -A^-1 Ju exactly (no finite differences)."""
    accelerations(t, x, u, p, A, z)
    jacobians(t, x, u, p, z, Jx, Ju)
    kkt_matrix(t, x, p, A)


@njit(cache=True, error_model="numpy")
def singular_at(t, x, p):
    """True if the mass/constraint matrix at (t, x) is finite but singular for `solve`."""
    A = np.empty((K, K + 1))  # a spare column for solve
    z = np.ones(K)
    kkt_matrix(t, x, p, A)
    for i in range(K):
        for j in range(K):
            if not math.isfinite(A[i, j]):
                return False
    solve(A, z)
    return not math.isfinite(z[0])
