"""`System`: a compiled model with numeric parameter values.

State x = [q, qdot] (length 2n), inputs u (length n_u). Every method accepts a leading batch
axis (shape (..., 2n) and (..., n_u)) and returns the same leading shape; time may be a scalar
or broadcast against the batch.

Every argument is checked once, by the rules of `checks` (real, finite, in range), and every
result is finite: when finite arguments give a NaN or inf (an overflow, or a mass/constraint
matrix that is singular at that state), the method raises ValueError naming itself, the row,
and the argument of largest magnitude or the singular matrix. Only the `*_unchecked` methods
skip this, for the environments' hot path.
"""

from __future__ import annotations

import math
from pathlib import Path
from types import ModuleType

import numba
import numpy as np

from . import cache, checks, interpreted, physical, rows, stepping
from .methods import METHODS


def check_parameters(
    model_name: str, names, defaults, positive, given: dict, nonnegative=()
) -> np.ndarray:
    """Parameter vector from defaults and overrides, with errors that name the problem."""
    values = dict(zip(names, map(float, defaults)))
    for key, value in given.items():
        checks.parameter_name(key, names, model_name)
        values[key] = checks.parameter(model_name, key, value)
    for key, pos in zip(names, positive):
        if pos and not values[key] > 0:
            raise ValueError(
                f"Parameter {key!r} of {model_name} must be positive, got {values[key]}."
            )
    for key, nonneg in zip(names, nonnegative):
        if nonneg and not values[key] >= 0:
            raise ValueError(
                f"Parameter {key!r} of {model_name} must not be negative, got {values[key]}."
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
        self._no_input = np.zeros(self.n_u)
        self._p = self._checked(params or {})
        self.parameters: dict[str, float] = dict(zip(module.PARAMETERS, self._p.tolist()))
        self.units: dict[str, str] = dict(zip(module.PARAMETERS, module.UNITS))
        # whether the model declares each parameter positive (a mass, a length)
        self.positive: dict[str, bool] = dict(zip(module.PARAMETERS, map(bool, module.POSITIVE)))
        # the points an external force may act on: name -> its number of components
        self.points: dict[str, int] = dict(
            zip(getattr(module, "POINTS", ()), getattr(module, "POINT_DIMS", ()))
        )

    def __repr__(self) -> str:
        return f"System({self.name!r}, {self.parameters})"

    # pickling: carry the generated source, rebuild from the cache (never re-derive)
    def __reduce__(self):
        return (_rebuild, (self.name, self._m.KEY, self._source_text(), self.parameters))

    def _source_text(self) -> str:
        """The generated module's body (without the cache's stamp line)."""
        if self._source is None:
            text = cache.read_bytes(Path(self._m.__file__)).decode("utf-8")
            self._source = cache.body_of(text, self._m.KEY)
            if self._source is None:
                raise RuntimeError(f"{self._m.__file__} changed on disk since it was loaded.")
        return self._source

    def with_parameters(self, **params) -> System:
        """The same model with some parameter values changed."""
        return System(self._m, {**self.parameters, **params}, self._source)

    # ---- argument checking -------------------------------------------------------------
    def _state(self, x) -> np.ndarray:
        x = checks.real_array(x, "state", self.name)
        if x.ndim == 0 or x.shape[-1] != self.state_size:
            raise ValueError(
                f"{self.name}: expected state of shape (..., {self.state_size}) "
                f"[q, qdot] for coordinates {self.coordinates}, got {x.shape}."
            )
        return x

    def _input(self, u) -> np.ndarray:
        if u is None:
            return self._no_input
        u = checks.real_array(u, "input", self.name)
        if u.ndim == 0 or u.shape[-1] != self.n_u:
            raise ValueError(
                f"{self.name}: expected input of shape (..., {self.n_u}) for "
                f"inputs {self.inputs}, got {u.shape}."
            )
        return u

    def _batch(self, t, x, u=None, need_u=True):
        """Flatten (t, x, u) to contiguous writable float64 rows (one numba specialisation
        for every caller), check they are finite; return them and the leading shape."""
        x = self._state(x)
        u = self._input(u) if need_u else self._no_input
        t = checks.real_array(t, "time", self.name)
        lead = x.shape[:-1]
        if u.shape[:-1] != lead or t.ndim:
            lead = np.broadcast_shapes(lead, u.shape[:-1], t.shape)
        nb = math.prod(lead)
        X = _rows(x, lead, nb)
        U = _rows(u, lead, nb)
        if t.ndim == 0:
            T = np.empty(nb)
            T[:] = t
        else:
            T = _rows(t[..., None], lead, nb).reshape(nb)
        if not self._m.all_finite(T, X, U):
            for label, a in (("state", X), ("input", U), ("time", T)):
                if not np.isfinite(a).all():
                    raise ValueError(f"{self.name}: {label} contains NaN or inf.")
        return T, X, (U if need_u else None), lead

    def _finite(self, method: str, out: np.ndarray, T, X, U=None, dt=None) -> np.ndarray:
        """`out` (rows), or ValueError if finite arguments gave a non-finite row."""
        row = self._m.first_nonfinite(out.reshape(out.shape[0], -1)) if out.size else -1
        if row < 0:
            return out
        where = f"{self.name}.{method}: finite arguments gave a non-finite result at row {row}"
        if self._m.singular_at(T[row], X[row], self._p):
            raise ValueError(
                f"{where}: the mass/constraint matrix is singular at that state "
                f"(x = {X[row].tolist()}, t = {T[row]}); the coordinates or constraints "
                "degenerate there and the accelerations are undefined."
            )
        sizes = {"state": np.abs(X[row]).max(), "time": abs(T[row])}
        if U is not None and U.shape[1]:
            sizes["input"] = np.abs(U[row]).max()
        if dt is not None:
            sizes["dt"] = dt
        culprit = max(sizes, key=sizes.get)
        hint = " (or the motion diverges within dt: reduce dt)" if dt is not None else ""
        raise ValueError(
            f"{where}: {culprit} is out of range (largest magnitude {sizes[culprit]:.3g}); "
            f"the model's arithmetic overflows for values this large{hint}."
        )

    # ---- dynamics ----------------------------------------------------------------------
    def state_derivative(self, t, x, u=None) -> np.ndarray:
        """dx/dt = [qdot, qddot] at time t, state x, inputs u (zeros if None)."""
        T, X, U, lead = self._batch(t, x, u)
        out = np.empty_like(X)
        if X.shape[0] >= VECTORIZE_FROM:
            model = stepping.table(self._m, "derivative_lanes")
            stepping.derivative_rows(T, X, U, self._p, out, BLOCK, model)
        else:
            self._m.derivative_batch(T, X, U, self._p, out)
        return self._finite("state_derivative", out, T, X, U).reshape(lead + (self.state_size,))

    def accelerations(self, t, x, u=None) -> np.ndarray:
        """qddot, shape (..., n)."""
        return self._solve(t, x, u)[..., : self.n_q]

    def multipliers(self, t, x, u=None) -> np.ndarray:
        """The constraint multipliers lambda of eq. (7.36), shape (..., n_c)."""
        return self._solve(t, x, u)[..., self.n_q :]

    def _solve(self, t, x, u):
        T, X, U, lead = self._batch(t, x, u)
        out = np.empty((X.shape[0], self.n_q + self.n_c))
        compiled = cache.compiled(self._m.accelerations_batch)
        program = interpreted.accelerations_py
        if len(X) > interpreted.INTERPRETED_ROWS or not all(
            self._interpreted(program, T[b], X[b], U[b], out[b], compiled=compiled)
            for b in range(len(X))
        ):
            self._m.accelerations_batch(T, X, U, self._p, out)
        return self._finite("accelerations", out, T, X, U).reshape(lead + (self.n_q + self.n_c,))

    def step(
        self, x, u=None, dt: float = 0.01, substeps: int = 1, t=0.0, method: str = "rk4"
    ) -> np.ndarray:
        """Advance by dt with `substeps` fixed steps of `method` ("rk4" or "dop853", see
        `dynamics.methods`), u held constant (zero-order hold).

        dt: positive finite number, s; substeps: integer 1..checks.MAX_SUBSTEPS.
        Nonholonomic models are projected back onto their velocity constraints after each
        substep. Returns the new state (same shape as x, broadcast with u)."""
        dt = checks.time_step(self.name, dt)
        substeps = checks.substeps(self.name, substeps)
        tableau = method_tableau(method)
        T, X, U, lead = self._batch(t, x, u)
        out = np.empty_like(X)
        self._blocks(T, X, U, self._p, None, None, dt / substeps, substeps, *tableau, out)
        out = self._finite("step", out, T, X, U, dt=dt)
        return out.reshape(lead + (self.state_size,))

    def step_unchecked(
        self,
        T,
        X,
        U,
        dt: float,
        substeps: int,
        out: np.ndarray,
        method: str = "rk4",
        num_threads: int = 1,
        *,
        P=None,
        W=None,
        alone_below: int = stepping.LANES_FROM,
    ) -> None:
        """`step` on contiguous float64 rows T (N,), X (N, 2n), U (N, n_u) into `out`,
        without argument checks: the environments' hot path. P: the parameter values, one
        vector for every row (len(parameters),) or each row's own (N, len(parameters)),
        columns in the order of `parameters` (None: the system's); a row steps bit for bit
        as it would in a System with its values. W: generalised forces (N, n_q) added to
        the equations' forcing and held over dt (external pushes, see `point_forces`;
        W = 0 steps bit for bit as None), on one thread. Without W, blocks of BLOCK rows
        are spread over `num_threads` threads (numba's), and fewer than `alone_below` rows
        step one at a time (`erk_row`, as the lanes would): the same result bit for bit.

        Never raises for a bad row: where the integration fails (a singular mass/constraint
        matrix, an overflow) that row of `out` holds NaN or inf; the caller must check.
        Unchecked (P and W too)."""
        a, w, c = method_tableau(method)
        h = dt / substeps
        p, rows_p = (self._p, None) if P is None else (P, None) if P.ndim == 1 else (P[0], P)
        if W is None and num_threads > 1 and X.shape[0] > BLOCK:
            numba.set_num_threads(min(num_threads, numba.config.NUMBA_NUM_THREADS))
            name = "derivative_lanes" if rows_p is None else "derivative_lanes_p"
            model = stepping.table(self._m, name)
            stepping.erk_batch_parallel(T, X, U, p, rows_p, h, substeps, a, w, c, out, BLOCK, model)
        else:
            self._blocks(T, X, U, p, rows_p, W, h, substeps, a, w, c, out, alone_below)

    def _blocks(self, T, X, U, p, P, W, h, substeps, a, w, c, out, alone_below=None) -> None:
        """`stepping.erk_rows` over all rows, BLOCK rows a call: a loop here rather than a
        compiled one, whose compilation re-optimised all of erk_rows for a few microseconds
        a step saved; fewer than LANES_FROM rows without pushes by `erk_row`, one at a time
        (the same result), or fewer than `alone_below`."""
        n = X.shape[0]
        alone_below = stepping.LANES_FROM if alone_below is None else alone_below
        if n < alone_below and W is None:  # so few rows: one at a time, as erk_rows would
            model = stepping.table(self._m, "derivative_lanes")
            for r in range(n):
                stepping.erk_row(
                    T, X, U, p if P is None else P[r], h, substeps, a, w, c, out, r, model
                )
            return
        model = stepping.table(self._m, *stepping.lane_kernels(P is not None, W is not None))
        for lo in range(0, n, BLOCK):  # one call for an env's rows
            stepping.erk_rows(
                T, X, U, p, P, W, h, substeps, a, w, c, out, lo, min(n, lo + BLOCK), model
            )

    def point_forces(self, x, point: str, force, t=0.0) -> np.ndarray:
        """The generalised forces (..., n_q) of `force` (..., 2 or 3 components, in the basis
        of the point's declared velocity, N) acting at `point` (one of `points`) in states x:
        Q_s = force . dv/dqdot_s, by virtual work (`dynamics.spec.generalized_forces`)."""
        if point not in self.points:
            hint = checks.did_you_mean(point, self.points)
            raise ValueError(
                f"{self.name} has no point {point!r}.{hint} Known: "
                f"{', '.join(self.points) or 'none (ModelSpec.points)'}."
            )
        dims = self.points[point]
        f = checks.real_array(force, "force", self.name)
        if f.ndim == 0 or f.shape[-1] != dims:
            raise ValueError(
                f"{self.name}: a force at {point!r} has {dims} components, got shape {f.shape}."
            )
        T, X, _, lead = self._batch(t, x, need_u=False)
        F = _rows(f, lead, X.shape[0])
        if not np.isfinite(F).all():
            raise ValueError(f"{self.name}: force contains NaN or inf.")
        P = np.tile(self._p, (X.shape[0], 1))
        out = np.empty((X.shape[0], self.n_q))
        self._m.point_forces_batch(T, X, P, list(self.points).index(point), F, out)
        return self._finite("point_forces", out, T, X).reshape(lead + (self.n_q,))

    def check_parameter_rows(self, values: dict) -> None:
        """ValueError naming the problem unless every row of `values` (name -> (N,) array)
        gives valid parameters: known names, finite, positive where the model says so, and
        the model's conditions."""
        n = len(next(iter(values.values()))) if values else 0
        for b in range(n):
            self._checked({k: v[b] for k, v in values.items()}, self._p)

    def _checked(self, given: dict, base=None) -> np.ndarray:
        """The parameter vector of `given` over `base` (the defaults), checked: names, values,
        signs, the model's conditions and its bodies' inertia (`dynamics.physical`)."""
        m = self._m
        p = check_parameters(
            self.name,
            m.PARAMETERS,
            m.DEFAULTS if base is None else base,
            m.POSITIVE,
            given,
            getattr(m, "NONNEGATIVE", ()),
        )
        broken = physical.problems(m, p)
        if broken:
            shown = given or dict(zip(m.PARAMETERS, p.tolist()))
            raise ValueError(f"{self.name}: parameters {'; '.join(broken)} ({shown}).")
        return p

    @property
    def bodies(self) -> dict[str, tuple[str, ...]]:
        """The model's rigid bodies (`ModelSpec.bodies`): name -> the parameters its inertia
        reads. Values that make one impossible are refused like a broken condition."""
        return {name: reads for name, reads in physical.bodies(self._m)}

    @property
    def parameter_vector(self) -> np.ndarray:
        """The parameter values as the kernels take them: float64 (len(parameters),), in
        the order of `parameters` (a copy, the caller's to keep)."""
        return self._p.copy()

    @property
    def kernel_module(self) -> ModuleType:
        """The generated module of numba kernels (its `KEY` hashes all of its code), for
        code that calls them from its own compiled loops with its own parameter vector
        (`parameter_vector`) or rows of them (the environments' fused step)."""
        return self._m

    def project(self, x, t=0.0) -> np.ndarray:
        """x with its rates moved onto the velocity constraints (kinetic-energy metric)."""
        T, X, _, lead = self._batch(t, x, need_u=False)
        out = np.empty_like(X)
        rows.project_batch(T, X, self._p, out, stepping.table(self._m))
        return self._finite("project", out, T, X).reshape(lead + (self.state_size,))

    # ---- diagnostics -------------------------------------------------------------------
    def energy_terms(self, x, t=0.0) -> np.ndarray:
        """[T, V], shape (..., 2)."""
        T, X, _, lead = self._batch(t, x, need_u=False)
        out = np.empty((X.shape[0], 2))
        model = stepping.table(self._m, "energy_terms")
        rows.state_batch(T, X, self._p, None, out, model, stepping.AT_ENERGY)
        return self._finite("energy", out, T, X).reshape(lead + (2,))

    def energy(self, x, t=0.0) -> np.ndarray:
        """Total mechanical energy T + V, J (shape x.shape[:-1])."""
        return self.energy_terms(x, t).sum(axis=-1)

    def constraint_residual(self, x, t=0.0) -> np.ndarray:
        """B(q, t) qdot + b(q, t) of the nonholonomic constraints, shape (..., n_c)."""
        T, X, _, lead = self._batch(t, x, need_u=False)
        out = np.empty((X.shape[0], self.n_c))
        model = stepping.table(self._m, "residual")
        rows.state_batch(T, X, self._p, None, out, model, stepping.AT_RESIDUAL)
        return self._finite("constraint_residual", out, T, X).reshape(lead + (self.n_c,))

    def power(self, t, x, u=None) -> np.ndarray:
        """Power of the given non-conservative forces and of prescribed-motion drives, W.
        For a model with no other time dependence, d(T + V)/dt equals it."""
        T, X, U, lead = self._batch(t, x, u)
        out = np.empty((X.shape[0], 1))
        model = stepping.table(self._m, "accelerations", "power_out")
        rows.power_batch(T, X, U, self._p, out, model)
        return self._finite("power", out, T, X, U).reshape(lead)

    def outputs(self, t, x, u=None) -> dict[str, np.ndarray]:
        """Named derived quantities (e.g. the torque that keeps a prescribed rotation)."""
        T, X, U, lead = self._batch(t, x, u)
        out = np.empty((X.shape[0], len(self.output_names)))
        model = stepping.table(self._m, "accelerations", "outputs")
        rows.outputs_batch(T, X, U, self._p, None, out, model)
        out = self._finite("outputs", out, T, X, U)
        return {k: out[:, i].reshape(lead) for i, k in enumerate(self.output_names)}

    def kkt(self, x, u=None, t=0.0) -> tuple[np.ndarray, np.ndarray]:
        """(A, r) at one state: the mass/constraint matrix A = [[M, B^T], [B, 0]] (K x K) and
        the right-hand side r = [F, gamma] of A [qddot; lambda] = r, eq. (7.36)."""
        T, X, U, lead = self._batch(t, x, u)
        if lead != ():
            raise ValueError(f"{self.name}: kkt takes one state (no batch axis); got {lead}.")
        k = self.n_q + self.n_c
        A = np.empty((k, k + 1))
        r = np.empty(k)
        if not self._interpreted(interpreted.kkt_py, T[0], X[0], U[0], A, r):
            self._m.kkt(T[0], X[0], U[0], self._p, A, r)
        self._finite("kkt", np.concatenate([A[:, :k].ravel(), r])[None, :], T, X, U)
        return A[:, :k], r

    def _interpreted(self, program, t, x, u, *out, compiled: bool | None = None) -> bool:
        """`interpreted.run` of `program` on one point with this system's parameters."""
        return interpreted.run(self._m, self._p, program, t, x, u, *out, compiled=compiled)

    def linearize(self, x0, u0=None, t=0.0) -> tuple[np.ndarray, np.ndarray]:
        """(A, B) with d(dx)/dt = A dx + B du about (x0, u0), from symbolic Jacobians."""
        T, X, U, lead = self._batch(t, x0, u0)
        if lead != ():
            raise ValueError(
                f"{self.name}: linearize takes one state, one input and one time (no batch "
                f"axis); got leading shape {lead}."
            )
        n, k = self.n_q, self.n_q + self.n_c
        Am = np.empty((k, k + 1))  # the kernels' solve keeps row scales in a spare column
        z = np.empty(k)
        Jx = np.empty((k, 2 * n))
        Ju = np.empty((k, self.n_u))
        if not self._interpreted(interpreted.linear_terms_py, T[0], X[0], U[0], Am, z, Jx, Ju):
            self._m.linear_terms(T[0], X[0], U[0], self._p, Am, z, Jx, Ju)
        terms = np.concatenate([z, Jx.ravel(), Ju.ravel()])[None, :]
        self._finite("linearize", terms, T, X, U)
        with np.errstate(all="ignore"):
            dz = -np.linalg.solve(Am[:, :k], np.hstack([Jx, Ju]))
        self._finite("linearize", dz.reshape(1, -1), T, X, U)
        A = np.zeros((2 * n, 2 * n))
        A[:n, n:] = np.eye(n)
        A[n:, :] = dz[:n, : 2 * n]
        B = np.zeros((2 * n, self.n_u))
        B[n:, :] = dz[:n, 2 * n :]
        return A, B


BLOCK = 64
"""Rows integrated together in vector lanes, and the unit of work of a thread
(benchmarks/derivation.py measures the choice)."""


def method_tableau(method: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(a, b, c) of the integrator named `method`; ValueError naming the known ones."""
    tableau = METHODS.get(method) if isinstance(method, str) else None
    if tableau is None:
        raise checks.unknown("integrator", method, checks.INTEGRATORS)
    return tableau.a, tableau.b, tableau.c


VECTORIZE_FROM = 1
"""Batch size from which state_derivative evaluates rows in vector lanes (`derivative_rows`,
the integrators' evaluation) rather than one at a time with a pivoting solve: every size.
Measured faster from one row (the arm: 1.4e6 against 1.3e6 rows/s; 9x at 1024 rows; 8x for a
chain of seven links on a cart), and a row's result is the same bits in any batch."""


def _rows(a: np.ndarray, lead: tuple, nb: int) -> np.ndarray:
    if a.shape[:-1] != lead:
        a = np.broadcast_to(a, lead + a.shape[-1:])
    a = np.ascontiguousarray(a.reshape(nb, a.shape[-1]))
    return a if a.flags.writeable else a.copy()


def _rebuild(name: str, key: str, source: str, params: dict) -> System:
    return System(cache.load(name, key, source), params, source)
