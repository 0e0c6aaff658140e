"""`System`: a compiled model with numeric parameter values.

State x = [q, qdot] (length 2n), inputs u (length n_u). Every method accepts a leading batch
axis (shape (..., 2n) and (..., n_u)) and returns the same leading shape; time may be a scalar
or broadcast against the batch.
"""

from __future__ import annotations

import difflib
from types import ModuleType

import numpy as np

from . import cache


def check_parameters(model_name: str, names, defaults, positive, given: dict) -> np.ndarray:
    """Parameter vector from defaults and overrides, with errors that name the problem."""
    values = dict(zip(names, map(float, defaults)))
    for key, value in given.items():
        if key not in values:
            close = difflib.get_close_matches(key, names, n=1)
            hint = f" Did you mean {close[0]!r}?" if close else ""
            raise ValueError(
                f"Unknown parameter {key!r} for {model_name}.{hint} Known: {', '.join(names)}."
            )
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise TypeError(
                f"Parameter {key!r} of {model_name} must be a number, got {value!r}."
            ) from None
        if not np.isfinite(v):
            raise ValueError(f"Parameter {key!r} of {model_name} must be finite, got {v}.")
        values[key] = v
    for key, pos in zip(names, positive):
        if pos and not values[key] > 0:
            raise ValueError(
                f"Parameter {key!r} of {model_name} must be positive, got {values[key]}."
            )
    return np.array([values[k] for k in names], dtype=np.float64)


class System:
    """Numeric dynamics of a model: derivatives, energy, constraints, linearisation, RK4."""

    def __init__(self, module: ModuleType, params: dict | None = None, source: str | None = None):
        self._m = module
        self._source = source
        self.name: str = module.NAME
        self.coordinates: tuple[str, ...] = module.COORDINATES
        self.inputs: tuple[str, ...] = module.INPUTS
        self.output_names: tuple[str, ...] = module.OUTPUTS
        self.n_q, self.n_u, self.n_c = module.N_Q, module.N_U, module.N_C
        self.state_size = 2 * self.n_q
        self._p = check_parameters(
            self.name, module.PARAMETERS, module.DEFAULTS, module.POSITIVE, params or {}
        )
        self.parameters: dict[str, float] = dict(zip(module.PARAMETERS, self._p.tolist()))
        self.units: dict[str, str] = dict(zip(module.PARAMETERS, module.UNITS))

    def __repr__(self) -> str:
        return f"System({self.name!r}, {self.parameters})"

    # pickling: carry the generated source, rebuild from the cache (never re-derive)
    def __reduce__(self):
        return (_rebuild, (self.name, self._m.KEY, self._source_text(), self.parameters))

    def _source_text(self) -> str:
        if self._source is None:
            with open(self._m.__file__, encoding="utf-8") as fh:
                self._source = fh.read()
        return self._source

    def with_parameters(self, **params) -> System:
        """The same model with some parameter values changed."""
        return System(self._m, {**self.parameters, **params}, self._source)

    # ---- argument checking -------------------------------------------------------------
    def _state(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        if x.ndim == 0 or x.shape[-1] != self.state_size:
            raise ValueError(
                f"{self.name}: expected state of shape (..., {self.state_size}) "
                f"[q, qdot] for coordinates {self.coordinates}, got {x.shape}."
            )
        if not np.isfinite(x).all():
            raise ValueError(f"{self.name}: state contains NaN or inf.")
        return x

    def _input(self, u, lead: tuple) -> np.ndarray:
        if u is None:
            u = np.zeros(self.n_u)
        u = np.asarray(u, dtype=np.float64)
        if u.ndim == 0 or u.shape[-1] != self.n_u:
            raise ValueError(
                f"{self.name}: expected input of shape (..., {self.n_u}) for "
                f"inputs {self.inputs}, got {u.shape}."
            )
        if not np.isfinite(u).all():
            raise ValueError(f"{self.name}: input contains NaN or inf.")
        return u

    def _batch(self, t, x, u=None, need_u=True):
        """Flatten (t, x, u) to contiguous 2-D rows; return them and the leading shape."""
        x = self._state(x)
        if need_u:
            u = self._input(u, x.shape[:-1])
            lead = np.broadcast_shapes(x.shape[:-1], u.shape[:-1])
        else:
            lead = x.shape[:-1]
        t = np.asarray(t, dtype=np.float64)
        if not np.isfinite(t).all():
            raise ValueError(f"{self.name}: time contains NaN or inf.")
        lead = np.broadcast_shapes(lead, t.shape)
        nb = int(np.prod(lead, dtype=np.int64))
        # fresh writable C arrays: one numba specialisation for every caller
        X = np.array(np.broadcast_to(x, lead + x.shape[-1:]).reshape(nb, -1), order="C")
        T = np.array(np.broadcast_to(t, lead).reshape(nb), order="C")
        U = None
        if need_u:
            U = np.array(np.broadcast_to(u, lead + (self.n_u,)).reshape(nb, self.n_u), order="C")
        return T, X, U, lead

    # ---- dynamics ----------------------------------------------------------------------
    def state_derivative(self, t, x, u=None) -> np.ndarray:
        """dx/dt = [qdot, qddot] at time t, state x, inputs u (zeros if None)."""
        T, X, U, lead = self._batch(t, x, u)
        out = np.empty_like(X)
        self._m.derivative_batch(T, X, U, self._p, out)
        return out.reshape(lead + (self.state_size,))

    def accelerations(self, t, x, u=None) -> np.ndarray:
        """qddot, shape (..., n)."""
        return self._solve(t, x, u)[..., : self.n_q]

    def multipliers(self, t, x, u=None) -> np.ndarray:
        """The constraint multipliers lambda of eq. (7.36), shape (..., n_c)."""
        return self._solve(t, x, u)[..., self.n_q :]

    def _solve(self, t, x, u):
        T, X, U, lead = self._batch(t, x, u)
        out = np.empty((X.shape[0], self.n_q + self.n_c))
        self._m.accelerations_batch(T, X, U, self._p, out)
        return out.reshape(lead + (self.n_q + self.n_c,))

    def step(self, x, u=None, dt: float = 0.01, substeps: int = 1, t=0.0) -> np.ndarray:
        """Advance by dt with `substeps` RK4 steps, u held constant (zero-order hold).

        Nonholonomic models are projected back onto their velocity constraints after each
        substep. Returns the new state (same shape as x, broadcast with u)."""
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a positive finite number, got {dt}.")
        if int(substeps) != substeps or substeps < 1:
            raise ValueError(f"substeps must be a positive integer, got {substeps}.")
        T, X, U, lead = self._batch(t, x, u)
        out = np.empty_like(X)
        self._m.rk4_batch(T, X, U, self._p, float(dt) / substeps, int(substeps), out)
        return out.reshape(lead + (self.state_size,))

    def step_unchecked(self, T, X, U, dt: float, substeps: int, out: np.ndarray) -> None:
        """`step` on contiguous float64 rows T (N,), X (N, 2n), U (N, n_u) into `out`,
        without argument checks: the environments' hot path."""
        self._m.rk4_batch(T, X, U, self._p, dt / substeps, substeps, out)

    def project(self, x, t=0.0) -> np.ndarray:
        """x with its rates moved onto the velocity constraints (kinetic-energy metric)."""
        T, X, _, lead = self._batch(t, x, need_u=False)
        out = np.empty_like(X)
        self._m.project_batch(T, X, self._p, out)
        return out.reshape(lead + (self.state_size,))

    # ---- diagnostics -------------------------------------------------------------------
    def energy_terms(self, x, t=0.0) -> np.ndarray:
        """[T, V], shape (..., 2)."""
        T, X, _, lead = self._batch(t, x, need_u=False)
        out = np.empty((X.shape[0], 2))
        self._m.energy_batch(T, X, self._p, out)
        return out.reshape(lead + (2,))

    def energy(self, x, t=0.0) -> np.ndarray:
        """Total mechanical energy T + V, J (shape x.shape[:-1])."""
        return self.energy_terms(x, t).sum(axis=-1)

    def constraint_residual(self, x, t=0.0) -> np.ndarray:
        """B(q, t) qdot + b(q, t) of the nonholonomic constraints, shape (..., n_c)."""
        T, X, _, lead = self._batch(t, x, need_u=False)
        out = np.empty((X.shape[0], self.n_c))
        self._m.residual_batch(T, X, self._p, out)
        return out.reshape(lead + (self.n_c,))

    def power(self, t, x, u=None) -> np.ndarray:
        """Power of the given non-conservative forces and of prescribed-motion drives, W.
        For a model with no other time dependence, d(T + V)/dt equals it."""
        T, X, U, lead = self._batch(t, x, u)
        out = np.empty((X.shape[0], 1))
        self._m.power_batch(T, X, U, self._p, out)
        return out.reshape(lead)

    def outputs(self, t, x, u=None) -> dict[str, np.ndarray]:
        """Named derived quantities (e.g. the torque that keeps a prescribed rotation)."""
        T, X, U, lead = self._batch(t, x, u)
        out = np.empty((X.shape[0], len(self.output_names)))
        self._m.outputs_batch(T, X, U, self._p, out)
        return {k: out[:, i].reshape(lead) for i, k in enumerate(self.output_names)}

    def linearize(self, x0, u0=None, t=0.0) -> tuple[np.ndarray, np.ndarray]:
        """(A, B) with d(dx)/dt = A dx + B du about (x0, u0), from symbolic Jacobians."""
        x0 = self._state(x0)
        u0 = self._input(u0, ())
        if x0.ndim != 1 or u0.ndim != 1:
            raise ValueError("linearize takes one state and one input (no batch axis).")
        n, k = self.n_q, self.n_q + self.n_c
        Am = np.empty((k, k))
        z = np.empty(k)
        Jx = np.empty((k, 2 * n))
        Ju = np.empty((k, self.n_u))
        self._m.linear_terms(
            float(t), np.ascontiguousarray(x0), np.ascontiguousarray(u0), self._p, Am, z, Jx, Ju
        )
        dz = -np.linalg.solve(Am, np.hstack([Jx, Ju]))
        A = np.zeros((2 * n, 2 * n))
        A[:n, n:] = np.eye(n)
        A[n:, :] = dz[:n, : 2 * n]
        B = np.zeros((2 * n, self.n_u))
        B[n:, :] = dz[:n, 2 * n :]
        return A, B


def _rebuild(name: str, key: str, source: str, params: dict) -> System:
    return System(cache.load(name, key, source), params, source)
