"""Model-independent numba kernels, appended to every generated model module.

They call the generated `kkt`, `kkt_matrix`, `residual` and `point_forces` and read the
constants N_Q, N_C, K of that module, so this file is a template and is never imported by
itself; what they share with every model (`solve`, `vsin`, ...) is imported from
`lanes.py`, and the integrator and the kernels over rows that only call the model's
kernels (`stepping.py`, `rows.py`) take them by address: both compiled once per machine.
Everything is batched over a leading axis and allocates its work arrays once per call. No
kernel raises on bad values (division by zero follows numpy's rules): a row whose result
is undefined comes back NaN, for the caller to see.
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
def accelerations_batch(T, X, U, p, out):
    A = np.empty((K, K + 1))  # a spare column for solve
    for b in range(X.shape[0]):
        accelerations(T[b], X[b], U[b], p, A, out[b])


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
