"""Model-independent numba functions that every generated model module imports: the
pivoting linear solve, the vectorisable sin and cos of the lane kernels, and the finiteness
scans. They live in a module of their own, not in the template `kernels.py`, so that numba
compiles them once per machine (its cache beside this file) instead of once per model: a
new model's first step then compiles only its own code."""

import math

import numpy as np
from numba import njit

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


# ---- sin and cos in vector lanes -----------------------------------------------------------
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
