"""Linear analysis of a compiled system: exact linearisation at an operating point, reduction
to the state components that matter, controllability, and zero-order-hold discretisation."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
import scipy.signal

from envs.plant import state_names

__all__ = [
    "Controllability",
    "LinearModel",
    "UncontrollableError",
    "controllability",
    "discretize",
    "linearize",
    "require_controllable",
    "state_names",
]


@dataclass(frozen=True)
class LinearModel:
    """d(dx)/dt = A dx + B du about (x0, u0), on the state components `states`."""

    A: np.ndarray
    B: np.ndarray
    x0: np.ndarray  # full physical state of the operating point, (2n,)
    u0: np.ndarray  # model inputs holding it, (n_u,)
    states: tuple[str, ...]  # names of the kept state components (rows of A)
    inputs: tuple[str, ...]  # names of the columns of B
    index: np.ndarray = field(repr=False)  # positions of `states` in the full state


def _indices(names: Sequence[str], keep: Sequence[str] | None) -> np.ndarray:
    if keep is None:
        return np.arange(len(names))
    unknown = [k for k in keep if k not in names]
    if unknown:
        raise ValueError(f"Unknown state components {unknown}. Known: {', '.join(names)}.")
    if len(set(keep)) != len(keep):
        raise ValueError(f"State components repeated in {list(keep)}.")
    return np.array([names.index(k) for k in keep])


def linearize(system, x0, u0, keep: Sequence[str] | None = None, t: float = 0.0) -> LinearModel:
    """Exact linearisation of `system` at (x0, u0), reduced to the state components `keep`.

    Dropping components is exact only if none of them drives a kept one at this operating
    point (true of cyclic coordinates and of rates fixed by the constraints); otherwise this
    raises ValueError naming the coupling. `keep` names come from `state_names(system)`.
    """
    names = state_names(system)
    x0 = np.asarray(x0, dtype=np.float64)
    u0 = np.zeros(system.n_u) if u0 is None else np.asarray(u0, dtype=np.float64)
    A, B = system.linearize(x0, u0, t)
    idx = _indices(names, keep)
    dropped = np.setdiff1d(np.arange(len(names)), idx)
    coupling = np.abs(A[np.ix_(idx, dropped)])
    scale = max(np.abs(A).max(), 1.0)
    if coupling.size and coupling.max() > 1e-10 * scale:
        i, j = np.unravel_index(np.argmax(coupling), coupling.shape)
        raise ValueError(
            f"Cannot drop {names[dropped[j]]!r}: it drives {names[idx[i]]!r} "
            f"(dA = {A[idx[i], dropped[j]]:.3g}) at this operating point."
        )
    return LinearModel(
        A=A[np.ix_(idx, idx)],
        B=B[idx],
        x0=x0,
        u0=u0,
        states=tuple(names[i] for i in idx),
        inputs=tuple(system.inputs),
        index=idx,
    )


class UncontrollableError(ValueError):
    """The linearised pair (A, B) has modes the inputs cannot reach."""


@dataclass(frozen=True)
class Controllability:
    """Controllability of (A, B).

    rank: numerical rank of [B, AB, ..., A^(n-1) B] (singular values above rtol * largest).
    condition: largest / smallest singular value of that matrix after scaling each state
        and input to unit norm (how hard the weakest direction is to reach; inf if rank < n).
    margin: min over eigenvalues lambda of A of the smallest singular value of
        [A - lambda I, B], relative to the norm of [A, B] (PBH test: 0 for a mode that
        cannot be reached; a distance-to-uncontrollability figure otherwise).
    unreachable: descriptions of the modes that cannot be reached (empty if controllable).
    """

    n: int
    rank: int
    condition: float
    margin: float
    unreachable: tuple[str, ...]

    @property
    def controllable(self) -> bool:
        return self.rank == self.n and not self.unreachable


def _mode_text(value: complex, vector: np.ndarray, states: Sequence[str]) -> str:
    w = np.abs(vector) / np.abs(vector).max()
    parts = [f"{states[i]} {w[i]:.2f}" for i in np.argsort(-w) if w[i] > 0.05]
    ev = f"{value.real:.4g}" if abs(value.imag) < 1e-12 else f"{value:.4g}"
    return f"eigenvalue {ev} (mode along {', '.join(parts)})"


def controllability(
    A: np.ndarray, B: np.ndarray, states: Sequence[str] | None = None, rtol: float = 1e-9
) -> Controllability:
    """Rank, conditioning and the unreachable modes (PBH test) of the pair (A, B)."""
    A = np.atleast_2d(np.asarray(A, dtype=np.float64))
    B = np.asarray(B, dtype=np.float64)
    n = A.shape[0]
    if A.shape != (n, n):
        raise ValueError(f"A must be square, got shape {A.shape}.")
    if B.ndim != 2 or B.shape[0] != n:
        raise ValueError(f"B must have shape ({n}, m) to match A, got {B.shape}.")
    states = tuple(states) if states is not None else tuple(f"x{i}" for i in range(n))
    # scale states and inputs so the figures do not depend on units
    d = np.linalg.norm(np.hstack([A, B]), axis=1)
    d[d == 0] = 1.0
    e = np.linalg.norm(B, axis=0)
    e[e == 0] = 1.0
    As, Bs = A / d[:, None] * d[None, :], B / d[:, None] / e[None, :]
    blocks = [Bs]
    for _ in range(n - 1):
        blocks.append(As @ blocks[-1])
    sv = np.linalg.svd(np.hstack(blocks), compute_uv=False)
    rank = int(np.sum(sv > rtol * sv[0])) if sv[0] > 0 else 0
    condition = float(sv[0] / sv[n - 1]) if rank == n else float("inf")

    norm = max(np.linalg.norm(np.hstack([As, Bs]), 2), 1e-300)
    values, left = scipy.linalg.eig(As, left=True, right=False)
    margin, unreachable = np.inf, []
    for k, lam in enumerate(values):
        M = np.hstack([As - lam * np.eye(n), Bs])
        s_min = np.linalg.svd(M, compute_uv=False)[-1] / norm
        margin = min(margin, s_min)
        if s_min <= rtol:
            # left eigenvector in the scaled coordinates -> physical state components
            unreachable.append(_mode_text(lam, left[:, k] / d, states))
    return Controllability(n, rank, condition, float(margin), tuple(dict.fromkeys(unreachable)))


def require_controllable(lin: LinearModel, rtol: float = 1e-9) -> Controllability:
    """`controllability` of a LinearModel; UncontrollableError naming the unreachable modes."""
    c = controllability(lin.A, lin.B, lin.states, rtol)
    if not c.controllable:
        modes = "; ".join(c.unreachable) or f"rank {c.rank} < {c.n}"
        raise UncontrollableError(
            f"(A, B) is not controllable from inputs {', '.join(lin.inputs)}: "
            f"controllability rank {c.rank} of {c.n}; unreachable: {modes}."
        )
    return c


def discretize(A: np.ndarray, B: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Zero-order-hold discretisation: x[k+1] = Ad x[k] + Bd u[k] with u held over dt."""
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a positive finite number, got {dt}.")
    n, m = np.shape(B)
    Ad, Bd, *_ = scipy.signal.cont2discrete((A, B, np.eye(n), np.zeros((n, m))), dt, "zoh")
    return Ad, Bd
