"""The model's per-row kernels over rows (energy and constraint residual: `state_batch`;
power, outputs, projection), compiled once per machine: each calls the model's kernel
through its address in the model's table (`dynamics.stepping.table`), as the integrator
does, instead of a copy per model that links it (about 0.1-0.5 s of CPU a model and
kernel). The same operations as the model's kernel called row by row, so the same results
bit for bit.

Rows are float64 and contiguous: T (N,), X (N, 2n), U (N, n_u), out (N, width); the
parameters p (n_p,) are one vector for every row, or P (N, n_p) each row's own (P None:
every row has p; numba prunes the other branch before compiling).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from . import calls
from .stepping import (
    ACCELERATIONS,
    AT_ACCELERATIONS,
    AT_OUTPUTS,
    AT_POWER,
    AT_PROJECT,
    ENERGY,
    N_C,
    OUTPUTS,
    POWER,
    PROJECT,
    RESIDUAL,
    K,
)

STATE = ENERGY
"""The label of a call of `energy_terms` or `residual`: the same argument types."""
assert STATE == RESIDUAL


@njit(cache=True, error_model="numpy")
def state_batch(T, X, p, P, out, model, kernel):
    """out[b] <- the model's kernel of the state, (t, x, p, out), at `model[kernel]` of
    every row: its `energy_terms` ([T, V], kernel AT_ENERGY) or its velocity-constraint
    `residual` (AT_RESIDUAL); both have that signature, so one compilation serves both."""
    for b in range(X.shape[0]):
        if P is None:
            calls.call(model[kernel], STATE, (T[b], X[b], p, out[b]))
        else:
            calls.call(model[kernel], STATE, (T[b], X[b], P[b], out[b]))


@njit(cache=True, error_model="numpy")
def outputs_batch(T, X, U, p, P, out, model):
    """The model's outputs of every row, after its accelerations (`accelerations`, then
    `outputs`)."""
    k = model[K]
    A = np.empty((k, k + 1))  # a spare column for solve
    z = np.empty(k)
    for b in range(X.shape[0]):
        if P is None:
            calls.call(model[AT_ACCELERATIONS], ACCELERATIONS, (T[b], X[b], U[b], p, A, z))
            calls.call(model[AT_OUTPUTS], OUTPUTS, (T[b], X[b], U[b], p, z, out[b]))
        else:
            pb = P[b]
            calls.call(model[AT_ACCELERATIONS], ACCELERATIONS, (T[b], X[b], U[b], pb, A, z))
            calls.call(model[AT_OUTPUTS], OUTPUTS, (T[b], X[b], U[b], pb, z, out[b]))


@njit(cache=True, error_model="numpy")
def power_batch(T, X, U, p, out, model):
    """The power of the given forces in every row (`accelerations`, then `power_out`)."""
    k = model[K]
    A = np.empty((k, k + 1))  # a spare column for solve
    z = np.empty(k)
    for b in range(X.shape[0]):
        calls.call(model[AT_ACCELERATIONS], ACCELERATIONS, (T[b], X[b], U[b], p, A, z))
        calls.call(model[AT_POWER], POWER, (T[b], X[b], U[b], p, z, out[b]))


@njit(cache=True, error_model="numpy")
def project_batch(T, X, p, out, model):
    """out <- every row of X projected onto its velocity constraints (`project`; a model
    without constraints has none to call)."""
    k = model[K]
    A = np.empty((k, k + 1))  # a spare column for solve
    z = np.empty(k)
    for b in range(X.shape[0]):
        for i in range(X.shape[1]):
            out[b, i] = X[b, i]
        if model[N_C]:
            calls.call(model[AT_PROJECT], PROJECT, (T[b], out[b], p, A, z))
