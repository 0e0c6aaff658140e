"""Model-independent numba kernels, appended to every generated model module.

They call the generated `kkt`, `kkt_matrix`, `residual`, `energy_terms`, `power_out`,
`outputs` and read the constants N_Q, N_C, K, N_OUT of that module, so this file is a
template and is never imported by itself. Everything is batched over a leading axis and
allocates its work arrays once per call. No kernel raises on bad values (division by zero
follows numpy's rules): a row whose result is undefined comes back NaN, for the caller to see.
"""
# ruff: noqa: F821
# --- template starts here ---


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
    kinetic-energy metric: qdot <- qdot + dv, [[M, B^T], [B, 0]] [dv; mu] = [0; -(B qdot + b)]."""
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
def accelerations_batch(T, X, U, p, out):
    A = np.empty((K, K + 1))  # a spare column for solve
    for b in range(X.shape[0]):
        accelerations(T[b], X[b], U[b], p, A, out[b])


@njit(cache=True, error_model="numpy")
def rk4_batch(T, X, U, p, h, substeps, out):
    """Classical RK4, `substeps` steps of size h per row, inputs held (zero-order hold).
    Constrained models are projected onto their velocity constraints after every step."""
    n2 = X.shape[1]
    A = np.empty((K, K + 1))  # a spare column for solve
    z = np.empty(K)
    x = np.empty(n2)
    xs = np.empty(n2)
    k1 = np.empty(n2)
    k2 = np.empty(n2)
    k3 = np.empty(n2)
    k4 = np.empty(n2)
    for b in range(X.shape[0]):
        u = U[b]
        t = T[b]
        for i in range(n2):
            x[i] = X[b, i]
        for _ in range(substeps):
            rhs(t, x, u, p, A, z, k1)
            for i in range(n2):
                xs[i] = x[i] + 0.5 * h * k1[i]
            rhs(t + 0.5 * h, xs, u, p, A, z, k2)
            for i in range(n2):
                xs[i] = x[i] + 0.5 * h * k2[i]
            rhs(t + 0.5 * h, xs, u, p, A, z, k3)
            for i in range(n2):
                xs[i] = x[i] + h * k3[i]
            rhs(t + h, xs, u, p, A, z, k4)
            for i in range(n2):
                x[i] += (h / 6.0) * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
            t += h
            project(t, x, p, A, z)
        for i in range(n2):
            out[b, i] = x[i]


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
