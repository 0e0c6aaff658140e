"""Model-independent numba kernels, appended to every generated model module.

They call the generated `kkt`, `kkt_matrix`, `residual`, `energy_terms`, `power_out`,
`outputs` and read the constants N_Q, N_C, K, N_OUT of that module, so this file is a
template and is never imported by itself. Everything is batched over a leading axis and
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

PIVOT_TOL = 64 * 2.220446049250313e-16
"""Smallest pivot of the row-scaled matrix: below it the matrix is singular to working
precision (condition number about 1e14 or more, fewer than two correct digits)."""


@njit(cache=True, error_model="numpy")
def fail(r):
    for i in range(r.shape[0]):
        r[i] = math.nan


@njit(cache=True, error_model="numpy")
def solve(A, r):
    """Solve A z = r in place (r <- z) by Gaussian elimination with partial pivoting.

    A is the small mass/constraint matrix, K x K, stored with one spare column (shape
    (K, K + 1)) that holds each row's largest entry; LAPACK's call overhead is several
    times the arithmetic at this size (see benchmarks/dynamics.py). A pivot below
    PIVOT_TOL times its row's largest entry (the matrix singular to working precision,
    whatever the scale of each row) or an empty row leaves NaN in r instead of raising.
    """
    k = r.shape[0]
    for i in range(k):
        s = 0.0
        for j in range(k):
            a = abs(A[i, j])
            if a > s:
                s = a
        if not (s > 0.0 and s < math.inf):
            fail(r)
            return
        A[i, k] = s
    for c in range(k):
        piv = c
        big = abs(A[c, c])
        for i in range(c + 1, k):
            if abs(A[i, c]) > big:
                big = abs(A[i, c])
                piv = i
        if not big > PIVOT_TOL * A[piv, k]:
            fail(r)
            return
        if piv != c:
            for j in range(k + 1):
                tmp = A[c, j]
                A[c, j] = A[piv, j]
                A[piv, j] = tmp
            tmp = r[c]
            r[c] = r[piv]
            r[piv] = tmp
        inv = 1.0 / A[c, c]
        for i in range(c + 1, k):
            f = A[i, c] * inv
            if f != 0.0:
                for j in range(c + 1, k):
                    A[i, j] -= f * A[c, j]
                r[i] -= f * r[c]
    for c in range(k - 1, -1, -1):
        s = r[c]
        for j in range(c + 1, k):
            s -= A[c, j] * r[j]
        r[c] = s / A[c, c]


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
# fdlibm's reduction by pi/2 in three parts (33 + 33 + 53 bits: k * PIO2_1 and k * PIO2_2 are
# exact for |k| < 2**20, |x| < 1.6e6) and its minimax kernels on [-pi/4, pi/4] (< 1 ulp).
TWO_OVER_PI = 6.36619772367581382433e-01
PIO2_1 = 1.57079632673412561417e00
PIO2_2 = 6.07710050630396597660e-11
PIO2_2T = 2.02226624879595063154e-21


@njit(cache=True, error_model="numpy")
def _reduce(x):
    """(r, quadrant) with x = r + quadrant * pi/2 (mod 2 pi), |r| <= pi/4, quadrant a
    float 0..3 (NaN for NaN or inf: no float-to-int conversion, whose out-of-range result
    LLVM may assume away), branch-free."""
    k = np.floor(x * TWO_OVER_PI + 0.5)
    r = ((x - k * PIO2_1) - k * PIO2_2) - k * PIO2_2T
    return r, k - 4.0 * np.floor(0.25 * k)


@njit(cache=True, error_model="numpy")
def _sin_kernel(r):
    z = r * r
    w = 8.33333333332248946124e-03 + z * (
        -1.98412698298579493134e-04
        + z
        * (
            2.75573137070700676789e-06
            + z * (-2.50507602534068634195e-08 + z * 1.58969099521155010221e-10)
        )
    )
    return r + (z * r) * (-1.66666666666666324348e-01 + z * w)


@njit(cache=True, error_model="numpy")
def _cos_kernel(r):
    z = r * r
    w = z * (
        4.16666666666666019037e-02
        + z
        * (
            -1.38888888888741095749e-03
            + z
            * (
                2.48015872894767294178e-05
                + z
                * (
                    -2.75573143513906633035e-07
                    + z * (2.08757232129817482790e-09 + z * -1.13596475577881948265e-11)
                )
            )
        )
    )
    hz = 0.5 * z
    v = 1.0 - hz
    return v + (((1.0 - v) - hz) + z * w)


@njit(cache=True, error_model="numpy")
def vsin(x):
    """sin(x) without a library call (vectorisable): within 2 ulp of libm for |x| < 1.6e6;
    beyond, its absolute error stays below the spacing of doubles at x. NaN for NaN, inf."""
    r, q = _reduce(x)
    s, c = _sin_kernel(r), _cos_kernel(r)
    v = c if (q == 1.0) | (q == 3.0) else s
    return -v if q >= 2.0 else v


@njit(cache=True, error_model="numpy")
def vcos(x):
    """cos(x) without a library call (vectorisable), accurate as `vsin`."""
    r, q = _reduce(x)
    s, c = _sin_kernel(r), _cos_kernel(r)
    v = s if (q == 1.0) | (q == 3.0) else c
    return -v if (q == 1.0) | (q == 2.0) else v


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
    and held over the step (external pushes; W = 0 steps bit for bit as W None)."""
    m = hi - lo
    if m < LANES_FROM and W is None:
        for r in range(lo, hi):
            if P is None:
                erk_row(T, X, U, p, h, substeps, a, w, c, out, r)
            else:
                erk_row(T, X, U, P[r], h, substeps, a, w, c, out, r)
        return
    n2 = X.shape[1]
    pc = np.empty((p.shape[0], 0 if P is None else m))  # the block's parameters, as columns
    if P is not None:
        for b in range(m):
            for i in range(p.shape[0]):
                pc[i, b] = P[lo + b, i]
    wc = np.empty((N_Q, 0 if W is None else m))  # the block's generalised forces, as columns
    if W is not None:
        for b in range(m):
            for i in range(N_Q):
                wc[i, b] = W[lo + b, i]
    s_count = w.shape[0]
    x = np.empty((n2, m))
    xs = np.empty((n2, m))
    k = np.empty((s_count, n2, m))
    u = np.empty((U.shape[1], m))
    t = np.empty(m)
    ts = np.empty(m)
    for b in range(m):
        t[b] = T[lo + b]
        for i in range(n2):
            x[i, b] = X[lo + b, i]
        for j in range(U.shape[1]):
            u[j, b] = U[lo + b, j]
    for _ in range(substeps):
        for s in range(s_count):
            for b in range(m):
                ts[b] = t[b] + c[s] * h
            if s == 0:
                if P is None:
                    derivative_lanes(ts, x, u, p, k[0])
                elif W is None:
                    derivative_lanes_p(ts, x, u, pc, k[0])
                else:
                    derivative_lanes_w(ts, x, u, pc, wc, k[0])
                continue
            for i in range(n2):
                for b in range(m):
                    xs[i, b] = 0.0
                for j in range(s):
                    f = a[s, j]
                    if f != 0.0:
                        for b in range(m):
                            xs[i, b] += f * k[j, i, b]
                for b in range(m):
                    xs[i, b] = x[i, b] + h * xs[i, b]
            if P is None:
                derivative_lanes(ts, xs, u, p, k[s])
            elif W is None:
                derivative_lanes_p(ts, xs, u, pc, k[s])
            else:
                derivative_lanes_w(ts, xs, u, pc, wc, k[s])
        for i in range(n2):
            for b in range(m):
                xs[i, b] = 0.0
            for s in range(s_count):
                f = w[s]
                if f != 0.0:
                    for b in range(m):
                        xs[i, b] += f * k[s, i, b]
            for b in range(m):
                x[i, b] += h * xs[i, b]
        for b in range(m):
            t[b] += h
        if N_C:
            project_columns(t, x, p, P, lo)
    for b in range(m):
        for i in range(n2):
            out[lo + b, i] = x[i, b]


LANES_FROM = 8
"""Blocks of fewer rows step one row at a time (`erk_row`): the column loops' set-up per
stage costs more than the arithmetic of a few rows (the single env: 150 ns against 20 ns
per derivative evaluation)."""


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


@njit(cache=True, error_model="numpy")
def erk_batch_rows(T, X, U, P, h, substeps, a, w, c, out, block):
    """`erk_batch` with each row's own parameters P (N, n_p)."""
    n = X.shape[0]
    for j in range((n + block - 1) // block):
        erk_rows(T, X, U, P[0], P, None, h, substeps, a, w, c, out, j * block,
                    min(n, (j + 1) * block))  # fmt: skip


@njit(cache=True, error_model="numpy", parallel=True)
def erk_batch_rows_parallel(T, X, U, P, h, substeps, a, w, c, out, block):
    """`erk_batch_rows` with the blocks spread over numba's threads."""
    n = X.shape[0]
    for j in prange((n + block - 1) // block):
        erk_rows(T, X, U, P[0], P, None, h, substeps, a, w, c, out, j * block,
                    min(n, (j + 1) * block))  # fmt: skip


@njit(cache=True, error_model="numpy")
def erk_batch_w(T, X, U, P, W, h, substeps, a, w, c, out, block):
    """`erk_batch_rows` with the generalised forces W (N, n_q) added to each row's forcing
    and held over the step (external pushes): `erk_rows` with W, block by block."""
    n = X.shape[0]
    for lo in range(0, n, block):
        erk_rows(T, X, U, P[0], P, W, h, substeps, a, w, c, out, lo, min(n, lo + block))


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
def outputs_batch_rows(T, X, U, P, out):
    """`outputs_batch` with each row's own parameters P (N, n_p)."""
    for b in range(X.shape[0]):
        outputs_batch(T[b : b + 1], X[b : b + 1], U[b : b + 1], P[b], out[b : b + 1])


@njit(cache=True, error_model="numpy")
def energy_batch_rows(T, X, P, out):
    """`energy_batch` with each row's own parameters P (N, n_p)."""
    for b in range(X.shape[0]):
        energy_terms(T[b], X[b], P[b], out[b])


@njit(cache=True, error_model="numpy")
def residual_batch_rows(T, X, P, out):
    """`residual_batch` with each row's own parameters P (N, n_p)."""
    for b in range(X.shape[0]):
        residual(T[b], X[b], P[b], out[b])


@njit(cache=True, error_model="numpy")
def project_batch_rows(T, X, P, out):
    """`project_batch` with each row's own parameters P (N, n_p)."""
    for b in range(X.shape[0]):
        project_batch(T[b : b + 1], X[b : b + 1], P[b], out[b : b + 1])


@njit(cache=True, error_model="numpy")
def erk_batch(T, X, U, p, h, substeps, a, w, c, out, block):
    """`erk_rows` over all rows, `block` rows at a time, on this thread."""
    n = X.shape[0]
    for j in range((n + block - 1) // block):
        erk_rows(T, X, U, p, None, None, h, substeps, a, w, c, out, j * block,
                 min(n, (j + 1) * block))  # fmt: skip


@njit(cache=True, error_model="numpy", parallel=True)
def erk_batch_parallel(T, X, U, p, h, substeps, a, w, c, out, block):
    """`erk_batch` with the blocks spread over numba's threads (numba.set_num_threads):
    bit for bit the same result."""
    n = X.shape[0]
    for j in prange((n + block - 1) // block):
        erk_rows(T, X, U, p, None, None, h, substeps, a, w, c, out, j * block,
                 min(n, (j + 1) * block))  # fmt: skip


@njit(cache=True, error_model="numpy")
def project_batch(T, X, p, out):
    A = np.empty((K, K + 1))  # a spare column for solve
    z = np.empty(K)
    for b in range(X.shape[0]):
        for i in range(X.shape[1]):
            out[b, i] = X[b, i]
        project(T[b], out[b], p, A, z)


@njit(cache=True, error_model="numpy")
def energy_batch(T, X, p, out):
    for b in range(X.shape[0]):
        energy_terms(T[b], X[b], p, out[b])


@njit(cache=True, error_model="numpy")
def residual_batch(T, X, p, out):
    for b in range(X.shape[0]):
        residual(T[b], X[b], p, out[b])


@njit(cache=True, error_model="numpy")
def power_batch(T, X, U, p, out):
    A = np.empty((K, K + 1))  # a spare column for solve
    z = np.empty(K)
    for b in range(X.shape[0]):
        accelerations(T[b], X[b], U[b], p, A, z)
        power_out(T[b], X[b], U[b], p, z, out[b])


@njit(cache=True, error_model="numpy")
def outputs_batch(T, X, U, p, out):
    A = np.empty((K, K + 1))  # a spare column for solve
    z = np.empty(K)
    for b in range(X.shape[0]):
        accelerations(T[b], X[b], U[b], p, A, z)
        outputs(T[b], X[b], U[b], p, z, out[b])


@njit(cache=True, error_model="numpy")
def linear_terms(t, x, u, p, A, z, Jx, Ju):
    """Fill z = [qddot, lambda], the matrix A = kkt(x), and Jx, Ju = dR/dx, dR/du of the
    residual R(x, u, z) = kkt(x) z - rhs(x, u), generated symbolically: then
    dz/dx = -A^-1 Jx and dz/du = -A^-1 Ju exactly (no finite differences)."""
    accelerations(t, x, u, p, A, z)
    jacobians(t, x, u, p, z, Jx, Ju)
    kkt_matrix(t, x, p, A)


@njit(cache=True, error_model="numpy")
def all_finite(T, X, U):
    """True if no entry of T, X, U is NaN or inf (one pass, no temporaries)."""
    for b in range(X.shape[0]):
        if not math.isfinite(T[b]):
            return False
        for i in range(X.shape[1]):
            if not math.isfinite(X[b, i]):
                return False
        for j in range(U.shape[1]):
            if not math.isfinite(U[b, j]):
                return False
    return True


@njit(cache=True, error_model="numpy")
def first_nonfinite(Y):
    """Index of the first row of Y holding NaN or inf, or -1."""
    for b in range(Y.shape[0]):
        for i in range(Y.shape[1]):
            if not math.isfinite(Y[b, i]):
                return b
    return -1


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
