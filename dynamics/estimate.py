"""Linear estimation for identification: base parameters, weighted least squares with
standard errors, and physically consistent fits.

Base parameters (as FIGAROH and Pinocchio reduce a torque regressor): the regressor's
columns are evaluated on random states, scaled to unit norm, and taken in an order of
preference; a column in the span of those kept before it (relative residual below
`DEPENDENT_TOL`) is dependent, W_D = W_I K, so the data determine only the base parameters
beta = theta_I + K theta_D. Preference: moments of inertia first, then masses, then the
rest, each in model order, so that a mass seen only through I + m d^2 is the one held at
its given value (the classical grouping into the inertia).

Standard errors: the rows of a record are not independent (smoothing and shared interval
ends correlate neighbours), so the covariance is the sandwich (A^T A)^-1 S (A^T A)^-1
with Newey and West's Bartlett-weighted S over `lag` neighbouring times.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
from scipy.optimize import lsq_linear, minimize

DEPENDENT_TOL = 1e-6
"""Relative residual of a column projected on the kept ones below which it is dependent:
random states give the structure to about 1e-12, so anything above 1e-6 is a direction
the equations really contain."""


@dataclass(frozen=True)
class Base:
    """The identifiable combinations: beta_i = theta_i + sum_d K[i, d] theta_d."""

    independent: list[int]  # indices into the unknowns
    dependent: list[int]
    K: np.ndarray  # (len(independent), len(dependent))


def preference(names: list[str], units: dict[str, str]) -> list[int]:
    """Indices of `names` in the order columns are tried (see the module docstring)."""
    rank = {"kg*m^2": 0, "kg": 1}
    return sorted(range(len(names)), key=lambda i: (rank.get(units.get(names[i]), 2), i))


def base(W: np.ndarray, order: list[int]) -> Base:
    """The base parameters of the regressor W (rows, k) on random states."""
    scale = np.linalg.norm(W, axis=0)
    scale[scale == 0] = 1.0
    Ws = W / scale
    kept: list[int] = []
    dependent: list[int] = []
    Q = np.zeros((W.shape[0], 0))
    for j in order:
        col = Ws[:, j]
        rest = col - Q @ (Q.T @ col)
        if np.linalg.norm(rest) > DEPENDENT_TOL * max(np.linalg.norm(col), 1e-300):
            Q = np.column_stack([Q, rest / np.linalg.norm(rest)])
            kept.append(j)
        else:
            dependent.append(j)
    kept.sort()
    dependent.sort()
    K = np.zeros((len(kept), len(dependent)))
    if dependent:
        K = np.linalg.lstsq(W[:, kept], W[:, dependent], rcond=None)[0]
        K[np.abs(K) < 1e-9 * max(1.0, np.abs(K).max())] = 0.0
    return Base(kept, dependent, K)


def combination(names: list[str], b: Base, i: int) -> str:
    """beta_i as text, e.g. 'Ibar1 + 0.25*m1'."""
    terms = [names[b.independent[i]]]
    for d, coef in zip(b.dependent, b.K[i]):
        if coef != 0.0:
            terms.append(f"{'-' if coef < 0 else '+'} {abs(coef):.6g}*{names[d]}")
    return " ".join(terms)


def hac_covariance(
    A: np.ndarray, r: np.ndarray, time: np.ndarray, lag: int, gram: np.ndarray | None = None
) -> np.ndarray:
    """Newey-West covariance of the least-squares solution of A beta = y with residuals r;
    rows with the same `time` (integers 0..) form one score, neighbours up to `lag` apart
    are correlated with Bartlett weights 1 - l / (lag + 1)."""
    k = A.shape[1]
    scores = np.zeros((int(time.max()) + 1, k))
    np.add.at(scores, time, A * r[:, None])
    S = scores.T @ scores
    for ell in range(1, lag + 1):
        w = 1.0 - ell / (lag + 1)
        C = scores[ell:].T @ scores[:-ell]
        S += w * (C + C.T)
    dof = max(A.shape[0] - k, 1) / A.shape[0]
    bread = np.linalg.pinv(A.T @ A if gram is None else gram)
    return bread @ S @ bread / dof


def scaled_lstsq(A: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, float]:
    """(beta, condition number of A with unit-norm columns)."""
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    As = A / scale
    sol, *_, sv = np.linalg.lstsq(As, y, rcond=None)
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")
    return sol / scale, cond


def compensated(A, y, C=None, c=None):
    """(R, z, G): a square system R beta ~ z with the same least-squares solution and
    quadratic form as the normal equations G beta = A^T y - c, G = A^T A - C (C, c: the
    expected second moments of the noise in the rows, removed; `identify._rate_noise`),
    R the Cholesky factor of G. Without C it is A, y themselves. None where G is not
    positive definite: in some direction the record's noise is larger than its signal."""
    if C is None:
        return A, y, A.T @ A
    G = A.T @ A - C
    b = A.T @ y - c
    try:
        R = np.linalg.cholesky(G).T
    except np.linalg.LinAlgError:
        return None
    return R, np.linalg.solve(R.T, b), G


# ---- physical consistency ----------------------------------------------------------------
_AXES = ("xx", "yy", "zz", "xy", "xz", "yz")


def bodies(names: list[str]) -> dict[str, dict[str, str]]:
    """Bodies whose full inertia is declared: parameters named <prefix><axes><suffix> with
    all of xx, yy and zz present (products optional), e.g. I_Bxx, I_Byy, I_Bzz, I_Bxz."""
    found: dict[tuple, dict[str, str]] = {}
    for name in names:
        for m in re.finditer("|".join(_AXES), name):
            found.setdefault((name[: m.start()], name[m.end() :]), {})[m.group()] = name
    return {f"{a}*{b}": axes for (a, b), axes in found.items() if {"xx", "yy", "zz"} <= set(axes)}


def inertia_matrix(axes: dict[str, str], value) -> np.ndarray:
    """The 3x3 inertia of a body from its declared entries (value: name -> number)."""
    get = {a: (value(axes[a]) if a in axes else 0.0) for a in _AXES}
    return np.array(
        [
            [get["xx"], get["xy"], get["xz"]],
            [get["xy"], get["yy"], get["yz"]],
            [get["xz"], get["yz"], get["zz"]],
        ]
    )


def violations(theta: dict[str, float], lower: dict[str, float], full: dict) -> list[str]:
    """What in `theta` is not physical: a value under its lower bound (masses, moments,
    friction), or a body's inertia that is not positive definite or breaks the triangle
    inequality (the principal moments: each at most the sum of the other two)."""
    out = [f"{k} = {theta[k]:.6g} < {lo:g}" for k, lo in lower.items() if theta[k] < lo]
    for body, axes in full.items():
        if not all(a in theta for a in axes.values()):
            continue
        ev = np.linalg.eigvalsh(inertia_matrix(axes, theta.__getitem__))
        if ev[0] <= 0:
            out.append(f"the inertia of {body} is not positive definite (eigenvalues {ev})")
        elif ev[0] + ev[1] < ev[2] * (1 - 1e-12):
            out.append(f"the inertia of {body} breaks the triangle inequality ({ev})")
    return out


def constrained_fit(A, y, beta0, lower_beta, full_checks) -> np.ndarray:
    """beta minimising |A beta - y| with theta(beta) physical: bounds alone by `lsq_linear`;
    with bodies' full inertias also positive definiteness and the triangle inequality by
    SLSQP (`full_checks(beta)` -> values that must be >= 0)."""
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    As = A / scale
    lo = lower_beta * scale
    res = lsq_linear(As, y, bounds=(lo, np.full_like(lo, np.inf)), method="bvls")
    beta = res.x / scale
    if full_checks is None or np.all(full_checks(beta) >= 0):
        return beta

    def cost(z):
        e = As @ z - y
        return 0.5 * e @ e

    cons = [{"type": "ineq", "fun": lambda z: full_checks(z / scale)}]
    out = minimize(
        cost,
        np.maximum(beta0 * scale, lo),
        jac=lambda z: As.T @ (As @ z - y),
        bounds=[(v, None) for v in lo],
        constraints=cons,
        method="SLSQP",
        options={"maxiter": 500, "ftol": 1e-14},
    )
    return out.x / scale
