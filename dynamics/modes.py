"""Modal analysis of small oscillations about an equilibrium (e.g. eq. 7.26 of the arm).

Near a stable equilibrium q0 the linearised equations are M qddot + K q = 0, with M the mass
matrix and K the Hessian of V at q0. Substituting q = phi cos(omega t) gives the generalised
symmetric eigenproblem K phi = omega^2 M phi, solved by `scipy.linalg.eigh`: natural
frequencies omega and mode shapes phi, normalised so that phi^T M phi = 1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from . import checks


@dataclass(frozen=True)
class Modes:
    """Natural frequencies (rad/s, ascending) and mode shapes (columns, M-normalised)."""

    frequencies: np.ndarray
    shapes: np.ndarray

    @property
    def periods(self) -> np.ndarray:
        """2 pi / omega, s."""
        return 2 * np.pi / self.frequencies


def _square_symmetric(name: str, a, n: int | None = None) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    if a.ndim != 2 or a.shape[0] != a.shape[1] or (n is not None and a.shape[0] != n):
        want = "square" if n is None else f"({n}, {n})"
        raise ValueError(f"{name} must be a {want} matrix, got shape {a.shape}.")
    if not np.isfinite(a).all():
        raise ValueError(f"{name} contains NaN or inf.")
    if not np.allclose(a, a.T, rtol=1e-10, atol=1e-12 * max(1.0, np.abs(a).max())):
        raise ValueError(f"{name} must be symmetric; largest asymmetry {np.abs(a - a.T).max()}.")
    return (a + a.T) / 2


def modes(mass, stiffness) -> Modes:
    """Natural frequencies and mode shapes of M qddot + K q = 0.

    mass: symmetric positive definite (n, n); stiffness: symmetric positive semi-definite
    (n, n) (a zero eigenvalue is a rigid-body mode of frequency 0). Raises ValueError for a
    bad shape, an asymmetric or indefinite mass matrix, or a negative stiffness direction
    (an unstable equilibrium has no oscillation there).
    """
    M = _square_symmetric("mass", mass)
    K = _square_symmetric("stiffness", stiffness, M.shape[0])
    try:
        lam, shapes = scipy.linalg.eigh(K, M)
    except np.linalg.LinAlgError:
        raise ValueError("mass must be positive definite.") from None
    tol = 1e-12 * max(1.0, np.abs(lam).max())
    if lam.min() < -tol:
        raise ValueError(
            f"stiffness has a negative direction (omega^2 = {lam.min():.6g}): the "
            "equilibrium is unstable and has no natural frequency there."
        )
    return Modes(frequencies=np.sqrt(np.clip(lam, 0.0, None)), shapes=shapes)


def mass_and_stiffness(model, q0, **params) -> tuple[np.ndarray, np.ndarray]:
    """M(q0) and K = d^2 V / dq^2 (q0) of a `Model` with these parameter values (defaults
    otherwise): the matrices of its small-oscillation equations M qddot + K dq = 0.

    q0 must be an equilibrium of the unforced model (dV/dq = 0 there); the model must have
    no constraints, prescribed motion or explicit time dependence in M and V.
    """
    import sympy as sp

    from .spec import t

    spec, derived = model.spec, model.derived
    if spec.constraints or spec.prescribed:
        raise ValueError(f"{model.name}: modal analysis needs an unconstrained, free model.")
    q = list(spec.coordinates)
    q0 = np.asarray(q0, dtype=np.float64)
    if q0.shape != (len(q),):
        raise ValueError(f"{model.name}: expected q0 of shape ({len(q)},), got {q0.shape}.")
    values = {str(k): v for k, v in model.parameters.items()}
    for key, value in params.items():
        checks.parameter_name(key, values, model.name)
        values[key] = checks.parameter(model.name, key, value)
    plain = [sp.Symbol(f"q{i}") for i in range(len(q))]
    subs = {qi.diff(t): 0 for qi in q} | dict(zip(q, plain))
    point = dict(zip(plain, q0)) | {s: values[str(s)] for s in spec.parameters}
    V = derived.potential.subs(subs)
    mass = derived.mass.subs(subs)
    if t in V.free_symbols or t in mass.free_symbols:
        raise ValueError(f"{model.name}: M or V depends on time; no fixed equilibrium.")
    gradient = np.array([float(V.diff(p).subs(point)) for p in plain])
    K = np.array(sp.hessian(V, plain).subs(point).evalf(), dtype=np.float64)
    scale = max(1.0, np.abs(K).max())
    if np.abs(gradient).max() > 1e-9 * scale:
        raise ValueError(f"{model.name}: q0 = {q0} is not an equilibrium (dV/dq = {gradient}).")
    M = np.array(mass.subs(point).evalf(), dtype=np.float64)
    return M, K


def small_oscillations(model, q0, **params) -> Modes:
    """`modes` of `model` about the equilibrium q0 (see `mass_and_stiffness`)."""
    return modes(*mass_and_stiffness(model, q0, **params))
