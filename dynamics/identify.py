"""System identification: a model's parameters fitted to a recorded trajectory.

    >>> from dynamics.identify import identify
    >>> fit = identify("two_link_arm", {"t": t, "q": q, "qd": qd, "u": u})
    >>> fit.parameters          # every parameter: compile(**fit.parameters) accepts it
    >>> fit.base, fit.unidentifiable, fit.std, fit.condition

The equations come from the model's own derivation (`dynamics.regressor`): linear in the
unknowns (default: the inertial parameters), reduced to the base parameters the equations
can determine (`dynamics.estimate`), with optional friction columns.

The record. `t` (T,) uniformly sampled, `q` (T, n), optional `qd` (T, n), `u` (T, n_u) in
the model's input order, each input held from its sample to the next (zero-order hold, as
an env steps; the last row's input is not used). Without `qd`, the rates are the
Savitzky-Golay derivative of `q` (`scipy.signal.savgol_filter`, cubic, a `window` of 0.1 s
unless given). With `qd`, a record whose positions and rates disagree beyond integration
error (`NOISY`) is smoothed by the same filter, inputs too (a linear filter applied to both
sides of the equations keeps them paired); `window=0` never smooths.

The rows. Unconstrained models: Lagrange's equations integrated over windows of `span`
samples (default 0.1 s), p(x_end) - p(x_start) = integral of g, the integral by Simpson's
rule on each sampling interval with the midpoint state from cubic Hermite interpolation of
(q, q') at its ends (errors of order h^4: noise-free records fit to about 1e-8, with no
differentiation of the data). Constrained models: M q'' - F at each interval's midpoint,
with q'' = (q'(t1) - q'(t0)) / h, projected on the null space of the constraint matrix B
(N^T B^T lambda = 0 removes the unknown constraint forces).

The fit. Weighted least squares (each equation weighted by the inverse rms of its
residual in a first unweighted fit), standard errors by the Newey-West sandwich
(`estimate.hac_covariance`); when the estimates are not physical (a mass, moment or friction
coefficient below zero; a body's full inertia not positive definite or against the triangle
inequality), the fit is repeated with those constraints. Unknowns that enter nonlinearly
are held at their given values in the linear fit, then every estimated parameter is
refined by simulation error (multiple shooting over `SEGMENT` s, `scipy.optimize.least_squares`).
Parameters the data cannot determine are held at their given values and listed in
`unidentifiable` with the combination they enter through; they are never estimated.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.signal import savgol_filter

from . import estimate
from .regressor import (
    COULOMB_WIDTH,
    Regressor,
    as_model,
    friction_names,
    friction_setting,
    inertial,
    with_friction,
)

WINDOW = 0.1
"""Savitzky-Golay window (s) for rates from positions when none is given."""
SMOOTH = 0.3
"""Savitzky-Golay window (s) of a noisy record's accelerations (constrained models) when
none is given: the noise of (s(t1) - s(t0)) / h falls as the window's -3/2 power; on the
rolling disk (sensor noise 1e-2 rad/s) 0.1 s left the rates' noise above the signal of
some combinations, 0.3 s fitted within 1.2 %."""
SPAN = 0.1
"""Integration window (s) of a row of the momentum form."""
NOISY = 1e-2
"""Rms of q(t1) - q(t0) - h (q'(t0) + q'(t1)) / 2 over that of h q' above which a record is
taken to carry measurement noise (noise-free records at 100 Hz: about 1e-4 or less)."""
RANDOM_STATES = 200
"""States on which the base parameters are found."""
SEGMENT = 0.5
"""Length (s) of a simulation-error segment (multiple shooting)."""
POLYORDER = 3


@dataclass
class Identification:
    """The result of `identify` (units: the model's).

    parameters: every parameter of the model by name (unknowns at their estimates, the rest
        and the unidentifiable ones at their given values): `Model.compile(**parameters)`
        and `gym.make(env_id, **parameters)` accept it.
    std: standard error of each estimated parameter (NaN for the unidentifiable).
    base: the identifiable combinations (text, e.g. 'Ibar1 + 0.25*m1') and their values;
        base_std their standard errors.
    unidentifiable: {parameter: why}, the unknowns the equations do not determine.
    nonlinear: the unknowns that enter nonlinearly (refined by simulation error).
    friction: {coordinate: {"viscous": b, "coulomb": c}} where friction was fitted.
    residual_rms: {coordinate: rms of the fit's equation residual} (generalised forces).
    condition: condition number of the record's base regressor (unit-norm columns);
        above about 1e4 the record excites some combination poorly.
    violated: what the unconstrained fit broke (empty if it was physical).
    """

    parameters: dict[str, float]
    std: dict[str, float]
    base: dict[str, float]
    base_std: dict[str, float]
    unidentifiable: dict[str, str]
    nonlinear: tuple[str, ...]
    friction: dict[str, dict[str, float]]
    residual_rms: dict[str, float]
    condition: float
    violated: list[str] = field(default_factory=list)
    unknown: tuple[str, ...] = ()
    fitted: dict = field(default_factory=dict)
    """The record's equations as fitted: time (rows,), measured and predicted (rows, n_eq):
    the generalised forces of the inputs (and of everything not unknown) against the model's
    prediction (the momentum form: averaged over each window)."""


def identify(
    model,
    data,
    unknown=None,
    friction=None,
    *,
    given: dict | None = None,
    window: int | None = None,
    span: int | None = None,
    width: float = COULOMB_WIDTH,
    refine: bool | None = None,
    noise: tuple[float, float] | None = None,
    seed: int = 0,
) -> Identification:
    """Fit `model`'s `unknown` parameters to the record `data` (see the module docstring).

    model: a `dynamics.Model`, a registered name, a ModelSpec or a factory.
    data: mapping with t (T,), q (T, n), optional qd (T, n), u (T, n_u).
    unknown: parameter names (default: the inertial ones, unit kg or kg*m^2).
    friction: None, "all", or {coordinate: "viscous" | "coulomb" | "viscous+coulomb"}.
    given: values of the other parameters (default the model's), and the values the
        unidentifiable and nonlinear unknowns start from.
    window: Savitzky-Golay window in samples (odd; 0: no smoothing; None: see NOISY).
    span: samples per row of the momentum form (None: SPAN seconds).
    width: rate scale of the smooth Coulomb term tanh(q'/width).
    refine: simulation-error refinement (None: when some unknown enters nonlinearly).
    noise: the sensors' noise std (positions, rates) where known; None estimates whether
        there is noise (NOISY) and the rates' std (`_rate_noise`) from the record.
    """
    base_model = as_model(model)
    setting = friction_setting(base_model, friction)
    full = with_friction(base_model, setting, width)
    names = list(full.parameters)
    unknown = _unknown(base_model, unknown) + [
        p for c, kind in setting.items() for p, k in zip(friction_names(c), ("viscous", "coulomb"))
        if k in kind
    ]  # fmt: skip
    values = dict(full.parameters) | _given(full, given)
    rec = _record(data, len(full.coordinates), len(full.inputs), noise)
    reg = Regressor(full, unknown)
    lin = list(reg.linear)
    p = np.array([values[k] for k in names])
    rows = _rows(reg, rec, p, window, span)
    b = estimate.base(_random_regressor(reg, rec, p, seed), estimate.preference(lin, full.units))
    fit = _fit(rows, lin, b, values, full)
    fitted = _fitted(rows, rec, lin, b, fit)
    if refine is None:
        refine = bool(reg.nonlinear)
    if refine:
        fit = _refine(full, rec, fit, list(reg.nonlinear) + [lin[i] for i in b.independent])
    out = _result(base_model, full, setting, unknown, reg, b, fit)
    out.fitted = fitted
    return out


def _fitted(rows: Rows, rec: Record, lin, b, fit) -> dict:
    theta = np.array([fit.theta[k] for k in lin])
    times = rows.time.reshape(-1, rows.n_eq)[:, 0]
    scale = (len(rec.t) - 1) / max(times.max() + 1, 1)
    return {
        "time": rec.t[0] + (times + 0.5) * scale * rec.h,
        "measured": rows.y.reshape(-1, rows.n_eq),
        "predicted": (rows.A @ theta).reshape(-1, rows.n_eq),
    }


# ---- arguments ---------------------------------------------------------------------------
def _unknown(model, unknown) -> list[str]:
    names = list(model.parameters)
    if unknown is None:
        unknown = inertial(model)
        if not unknown:
            raise ValueError(f"{model.name} has no inertial parameters; name the unknowns.")
    if isinstance(unknown, str):
        unknown = [unknown]
    for name in unknown:
        if name not in names:
            close = difflib.get_close_matches(str(name), names, n=1)
            hint = f" Did you mean {close[0]!r}?" if close else ""
            raise ValueError(
                f"unknown: {model.name} has no parameter {name!r}.{hint} Known: {', '.join(names)}."
            )
    if len(set(unknown)) != len(unknown):
        raise ValueError(f"unknown: repeated names in {list(unknown)}.")
    return [n for n in names if n in unknown]  # model order


def _given(model, given) -> dict[str, float]:
    given = dict(given or {})
    for name in given:
        if name not in model.parameters:
            close = difflib.get_close_matches(str(name), list(model.parameters), n=1)
            hint = f" Did you mean {close[0]!r}?" if close else ""
            raise ValueError(f"given: {model.name} has no parameter {name!r}.{hint}")
    return {k: float(v) for k, v in given.items()}


@dataclass(frozen=True)
class Record:
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray | None
    u: np.ndarray
    h: float
    noise: tuple[float, float] | None = None


def _record(data, n: int, nu: int, noise=None) -> Record:
    """The record's arrays, checked: shapes, finite values, uniform sampling."""
    if not hasattr(data, "__getitem__") or not hasattr(data, "keys"):
        raise TypeError(f"data must be a mapping with t, q, [qd,] u; got {type(data).__name__}.")
    missing = [k for k in ("t", "q", "u") if k not in data.keys()]
    if missing:
        raise ValueError(f"data: missing {', '.join(missing)} (needs t, q, [qd,] u).")
    t = np.asarray(data["t"], dtype=float)
    T = len(t)
    arrays = {"q": (T, n), "u": (T, nu)} | ({"qd": (T, n)} if "qd" in data.keys() else {})
    got = {}
    for key, shape in arrays.items():
        a = np.asarray(data[key], dtype=float)
        if a.ndim == 1 and shape[1] == 1:
            a = a[:, None]
        if a.shape != shape:
            raise ValueError(f"data[{key!r}]: expected shape {shape}, got {a.shape}.")
        got[key] = a
    if t.ndim != 1 or T < 20:
        raise ValueError(f"data['t']: expected at least 20 samples in one axis, got {t.shape}.")
    for key, a in [("t", t), *got.items()]:
        if not np.isfinite(a).all():
            raise ValueError(f"data[{key!r}] contains NaN or inf.")
    dt = np.diff(t)
    h = float(np.mean(dt))
    if not h > 0 or np.abs(dt - h).max() > 1e-6 * h:
        raise ValueError("data['t'] must be increasing with a uniform step (resample first).")
    if noise is not None:
        noise = tuple(float(v) for v in noise)
        if len(noise) != 2 or not all(v >= 0 and math.isfinite(v) for v in noise):
            raise ValueError(f"noise must be two stds >= 0 (positions, rates), got {noise}.")
    return Record(t, got["q"], got.get("qd"), got["u"], h, noise)


# ---- rows of the regression --------------------------------------------------------------
@dataclass
class Rows:
    """The stacked regression A theta = y: rows with their equation and time indices."""

    A: np.ndarray  # (R, k)
    y: np.ndarray  # (R,)
    equation: np.ndarray  # (R,) int: the equation (coordinate, or projected equation)
    time: np.ndarray  # (R,) int: the window or interval
    lag: int  # neighbouring times whose residuals correlate
    to_coordinates: np.ndarray | None  # (times, n, n - m): projected -> coordinates
    n_eq: int
    # per equation: E[a a^T] and E[a e] of the rate noise in a row (a: its regressor noise,
    # e: its target noise), summed over the equation's rows; None for a noise-free record
    noise: tuple | None = None


def _noisy(rec: Record) -> bool:
    """Whether positions and rates disagree beyond integration error (see NOISY)."""
    if rec.qd is None:
        return True
    if rec.noise is not None:
        return max(rec.noise) > 0
    gap = rec.q[1:] - rec.q[:-1] - rec.h * (rec.qd[1:] + rec.qd[:-1]) / 2
    return bool(np.sqrt(np.mean(gap**2)) > NOISY * rec.h * np.sqrt(np.mean(rec.qd**2)))


def _signals(rec: Record, window: int | None, constrained: bool) -> tuple:
    """(q, qd, u, window used, noisy): the signals the rows are built from."""
    h, noisy = rec.h, _noisy(rec)
    default = max(2 * int(round(WINDOW / h / 2)) + 1, POLYORDER + 2 + (POLYORDER % 2))
    if window is not None and window != 0 and (window % 2 == 0 or window <= POLYORDER):
        raise ValueError(
            f"window must be 0 or an odd number of samples > {POLYORDER}, got {window}."
        )
    if rec.qd is None:
        w = window or default
        q = savgol_filter(rec.q, w, POLYORDER, axis=0)
        qd = savgol_filter(rec.q, w, POLYORDER, deriv=1, delta=h, axis=0)
        return q, qd, savgol_filter(rec.u, w, POLYORDER, axis=0), w, noisy
    if window is None:  # the momentum form averages noise itself; accelerations need it
        smooth = max(2 * int(round(SMOOTH / h / 2)) + 1, POLYORDER + 2 + (POLYORDER % 2))
        window = smooth if (noisy and constrained) else 0
    if window == 0:
        return rec.q, rec.qd, rec.u, 0, noisy
    smooth = [savgol_filter(a, window, POLYORDER, axis=0) for a in (rec.q, rec.qd, rec.u)]
    return *smooth, window, noisy


def _midpoints(q, qd, h, hermite: bool):
    """States at the intervals' midpoints: cubic Hermite from both ends (rates by its
    derivative where the record is exact, by the mean of the ends where it is noisy)."""
    qm = (q[:-1] + q[1:]) / 2 + h * (qd[:-1] - qd[1:]) / 8
    if hermite:
        qdm = 1.5 * (q[1:] - q[:-1]) / h - (qd[:-1] + qd[1:]) / 4
    else:
        qdm = (qd[:-1] + qd[1:]) / 2
    return np.hstack([qm, qdm])


def _rows(reg: Regressor, rec: Record, p, window, span) -> Rows:
    constrained = reg._m.N_C > 0
    q, qd, u, w, noisy = _signals(rec, window, constrained)
    h, t = rec.h, rec.t
    X = np.hstack([q, qd])
    mid = _midpoints(q, qd, h, hermite=not noisy and w == 0)
    lag = int(np.ceil(w / max(span or 1, 1))) + 1
    if constrained:
        qdd = (qd[1:] - qd[:-1]) / h
        rows = _acceleration_rows(reg, t[:-1] + h / 2, mid, qdd, u[:-1], p, w)
        if noisy and rec.qd is not None:
            rows.noise = _acceleration_noise(reg, rec, t[:-1] + h / 2, mid, qdd, u[:-1], p, w)
        return rows
    L = span or max(1, int(round(SPAN / h)))
    n_win = (len(t) - 1) // L
    if n_win < 2:
        raise ValueError(f"data: {len(t)} samples make fewer than 2 windows of {L}.")
    k = slice(0, n_win * L)
    P, p0, G0, g0 = reg.momentum(t, X, u, p)
    _, _, G1, g1 = reg.momentum(t[1:], X[1:], u[:-1], p)
    _, _, Gm, gm = reg.momentum(t[:-1] + h / 2, mid, u[:-1], p)
    IG = h / 6 * (G0[:-1] + 4 * Gm + G1)[k]
    Ig = h / 6 * (g0[:-1] + 4 * gm + g1)[k]
    n, nk = P.shape[1], P.shape[2]
    ends = np.arange(0, n_win + 1) * L
    A = (P[ends[1:]] - P[ends[:-1]] - IG.reshape(n_win, L, n, nk).sum(1)) / (L * h)
    y = -(p0[ends[1:]] - p0[ends[:-1]] - Ig.reshape(n_win, L, n).sum(1)) / (L * h)
    eq = np.tile(np.arange(n), n_win)
    time = np.repeat(np.arange(n_win), n)
    noise = _rate_noise(reg, rec, t, X, u, p, ends, L * h) if noisy and w == 0 else None
    return Rows(A.reshape(-1, nk), y.reshape(-1), eq, time, lag, None, n, noise)


def _rate_noise(reg, rec: Record, t, X, u, p, ends, span_s):
    """Second moments of the rate noise in the momentum rows, for bias compensation.

    A row's regressor and target hold the momenta at the window's ends, which are linear in
    the measured rates: noise n of std sigma_i in rate i puts J_i n into the row
    (J_i = dP/dqd_i, and dp0/dqd_i in the target), so least squares on noisy rows
    converges to (A^T A + E[N^T N])^-1 (A^T y + E[N^T e]), shrunk towards zero (errors in
    variables). The fit subtracts these expectations. sigma_i is estimated from the record
    (the rate's rms departure from its Savitzky-Golay smoothing, over sqrt(1 - c0), c0 the
    filter's centre weight)."""
    n = reg.n_q
    sigma = _rate_sigma(rec)
    Xe, te, ue = X[ends], t[ends], u[ends]
    P, p0, _, _ = reg.momentum(te, Xe, ue, p)
    k = P.shape[2]
    CA, cy = np.zeros((n, k, k)), np.zeros((n, k))
    for i in range(n):
        Xi = Xe.copy()
        Xi[:, n + i] += 1.0
        Pi, pi0, _, _ = reg.momentum(te, Xi, ue, p)
        J, j0 = (Pi - P) / span_s, -(pi0 - p0) / span_s  # per end: (ends, n, k), (ends, n)
        both = [slice(1, None), slice(None, -1)]  # every window has an end and a start
        for sl in both:
            CA += sigma[i] ** 2 * np.einsum("bek,bel->ekl", J[sl], J[sl])
            cy += sigma[i] ** 2 * np.einsum("bek,be->ek", J[sl], j0[sl])
    return CA, cy


def _rate_sigma(rec: Record) -> np.ndarray:
    """The rates' noise std: given, or estimated (see `_rate_noise`)."""
    from scipy.signal import savgol_coeffs

    if rec.noise is not None:
        return np.full(rec.q.shape[1], rec.noise[1])
    w = max(2 * int(round(WINDOW / rec.h / 2)) + 1, POLYORDER + 2 + (POLYORDER % 2))
    c0 = savgol_coeffs(w, POLYORDER)[w // 2]
    r = rec.qd - savgol_filter(rec.qd, w, POLYORDER, axis=0)
    return np.sqrt(np.mean(r**2, 0) / (1.0 - c0))


def _acceleration_noise(reg, rec: Record, T, X, QDD, U, p, w: int):
    """Second moments of the rate noise in the acceleration rows (as `_rate_noise` for the
    momentum form). With the rates smoothed by a filter of weights c (window w, or none),
    q'' = (s(t1) - s(t0)) / h carries noise of variance sigma^2 sum (c_j - c_(j-1))^2 / h^2
    and the midpoint rate (s(t0) + s(t1)) / 2 noise of variance sigma^2 sum ((c_j +
    c_(j-1)) / 2)^2, uncorrelated with the first (stationary noise). The rows are linear in
    q'' and, through the gyroscopic and centripetal terms, depend on the rates: both enter
    by their Jacobians (the rates' by central differences)."""
    from scipy.signal import savgol_coeffs

    c = savgol_coeffs(w, POLYORDER) if w else np.ones(1)
    padded = np.concatenate([[0.0], c, [0.0]])
    sigma2 = _rate_sigma(rec) ** 2
    var_qdd = sigma2 * np.sum(np.diff(padded) ** 2) / rec.h**2
    var_qd = sigma2 * np.sum(((padded[1:] + padded[:-1]) / 2) ** 2)
    n = reg.n_q
    B, _, _ = reg.constraints(T, X, p)
    Nsp = _null_spaces(B)

    def projected(Xa, QDDa):
        Y, y0 = reg.acceleration(T, Xa, QDDa, U, p)
        return np.einsum("bnr,bnk->brk", Nsp, Y), -np.einsum("bnr,bn->br", Nsp, y0)

    zero = np.zeros_like(QDD)
    A0, b0 = projected(X, zero)
    r, k = A0.shape[1], A0.shape[2]
    CA, cy = np.zeros((r, k, k)), np.zeros((r, k))
    for i in range(n):
        e = zero.copy()
        e[:, i] = 1.0
        Ai, bi = projected(X, e)
        J, j0 = Ai - A0, bi - b0
        CA += var_qdd[i] * np.einsum("brk,brl->rkl", J, J)
        cy += var_qdd[i] * np.einsum("brk,br->rk", J, j0)
        step = 1e-4 * max(1.0, float(np.abs(X[:, n + i]).max()))
        Xp, Xm = X.copy(), X.copy()
        Xp[:, n + i] += step
        Xm[:, n + i] -= step
        (Ap, bp), (Am, bm) = projected(Xp, QDD), projected(Xm, QDD)
        J, j0 = (Ap - Am) / (2 * step), (bp - bm) / (2 * step)
        CA += var_qd[i] * np.einsum("brk,brl->rkl", J, J)
        cy += var_qd[i] * np.einsum("brk,br->rk", J, j0)
    return CA, cy


def _null_spaces(B: np.ndarray) -> np.ndarray:
    """(N, n, n - m): orthonormal bases of the null spaces of B (N, m, n)."""
    m = B.shape[1]
    _, _, Vt = np.linalg.svd(B)
    return np.swapaxes(Vt[:, m:, :], 1, 2)


def _acceleration_rows(reg, T, X, QDD, U, p, w) -> Rows:
    Y, y0 = reg.acceleration(T, X, QDD, U, p)
    B, _, _ = reg.constraints(T, X, p)
    Nsp = _null_spaces(B)
    A = np.einsum("bnr,bnk->brk", Nsp, Y)
    y = -np.einsum("bnr,bn->br", Nsp, y0)
    times, r = A.shape[0], A.shape[1]
    eq = np.tile(np.arange(r), times)
    time = np.repeat(np.arange(times), r)
    return Rows(A.reshape(-1, A.shape[2]), y.reshape(-1), eq, time, max(w, 1), Nsp, r)


def _random_regressor(reg: Regressor, rec: Record, p, seed: int) -> np.ndarray:
    """The (projected) acceleration form on random states spanning the record's range."""
    rng = np.random.default_rng(seed)
    S, n = RANDOM_STATES, reg.n_q
    lo, hi = rec.q.min(0), rec.q.max(0)
    spread = np.maximum(hi - lo, 1e-3 * np.maximum(np.abs(hi), 1.0))
    q = lo + (hi - lo) / 2 + spread * (rng.random((S, n)) - 0.5)
    qd = rng.normal(size=(S, n))
    qdd = rng.normal(size=(S, n))
    T = rec.t[0] + (rec.t[-1] - rec.t[0]) * rng.random(S)
    U = rng.normal(size=(S, reg.n_u)) * (1.0 + rec.u.std(0))
    if reg._m.N_C:
        B, b, _ = reg.constraints(T, np.hstack([q, qd]), p)
        Nsp = _null_spaces(B)
        qd = np.einsum("bnr,bmr,bm->bn", Nsp, Nsp, qd)
        qd -= np.einsum("bnm,bm->bn", np.linalg.pinv(B), b)
        B, _, gamma = reg.constraints(T, np.hstack([q, qd]), p)
        qdd = np.einsum("bnr,bmr,bm->bn", Nsp, Nsp, qdd)
        qdd += np.einsum("bnm,bm->bn", np.linalg.pinv(B), gamma)
    rows = _acceleration_rows(reg, T, np.hstack([q, qd]), qdd, U, p, 1)
    return rows.A


# ---- the fit -----------------------------------------------------------------------------
@dataclass
class Fit:
    theta: dict[str, float]  # every parameter of the (friction) model
    std: dict[str, float]  # estimated unknowns
    beta: np.ndarray
    beta_std: np.ndarray
    residual_rms: np.ndarray  # per coordinate
    condition: float
    violated: list[str]


def _lower(full, names: list[str], values: dict) -> dict[str, float]:
    """Lower bounds of the physical unknowns: positive parameters above 1e-9 x their given
    value (so the model still compiles), friction coefficients at 0."""
    spec = {str(k): v for k, v in full.spec.parameters.items()}
    out = {}
    for name in names:
        if name.startswith(("viscous_", "coulomb_")) and spec[name].unit.startswith("force"):
            out[name] = 0.0
        elif spec[name].positive:
            out[name] = 1e-9 * abs(values[name]) if values[name] else 1e-12
    return out


def _fit(rows: Rows, lin: list[str], b: estimate.Base, values: dict, full) -> Fit:
    I, D, K = b.independent, b.dependent, b.K
    theta_D = np.array([values[lin[d]] for d in D])
    A, y = rows.A[:, I], rows.y  # A theta = A_I (theta_I + K theta_D) = A_I beta
    violated: list[str] = []

    def noise(w_eq):
        if rows.noise is None:
            return None, None
        CA, cy = rows.noise
        return (np.einsum("e,ekl->kl", w_eq**2, CA[:, I][:, :, I]),
                np.einsum("e,ek->k", w_eq**2, cy[:, I]))  # fmt: skip

    ones = np.ones(rows.n_eq)
    first = estimate.compensated(A, y, *noise(ones))
    if first is None:  # the noise outweighs the signal in some direction: fit as it is
        violated.append("the record's rate noise exceeds its signal in some direction: "
                        "no errors-in-variables compensation (expect estimates shrunk)")
        first = (A, y, A.T @ A)
        rows.noise = None
    beta, _ = estimate.scaled_lstsq(*first[:2])
    r = y - A @ beta
    sigma = np.array([np.sqrt(np.mean(r[rows.equation == e] ** 2)) for e in range(rows.n_eq)])
    w_eq = 1.0 / np.maximum(sigma, 1e-12 * max(sigma.max(), 1e-300))
    weighted = estimate.compensated(A * w_eq[rows.equation][:, None], y * w_eq[rows.equation],
                                    *noise(w_eq))  # fmt: skip
    if weighted is None:  # weighting made the noise outweigh a direction: equal weights
        w_eq = ones
        weighted = first
    w = w_eq[rows.equation]
    Aw, yw = A * w[:, None], y * w
    R, z, gram = weighted
    beta, cond = estimate.scaled_lstsq(R, z)

    def theta_of(beta_):
        return values | dict(zip([lin[i] for i in I], beta_ - K @ theta_D))

    lower = _lower(full, lin, values)
    bodies = estimate.bodies(list(values))
    unphysical = estimate.violations(theta_of(beta), lower, bodies)
    violated += unphysical
    if unphysical:
        lower_I = np.array([lower.get(lin[i], -np.inf) for i in I]) + K @ theta_D
        checks = _inertia_checks(bodies, theta_of) if any(
            set(axes.values()) & set(lin) for axes in bodies.values()
        ) else None  # fmt: skip
        beta = estimate.constrained_fit(R, z, beta, None, lower_I, checks)
    cov = estimate.hac_covariance(Aw, yw - Aw @ beta, rows.time, rows.lag, gram)
    beta_std = np.sqrt(np.maximum(np.diag(cov), 0.0))
    theta = theta_of(beta)
    std = {lin[i]: float(s) for i, s in zip(I, beta_std)}
    return Fit(theta, std, beta, beta_std, _residual_rms(rows, y - A @ beta), cond, violated)


def _inertia_checks(bodies: dict, theta_of):
    def checks(beta):
        theta = theta_of(beta)
        out = []
        for axes in bodies.values():
            ev = np.linalg.eigvalsh(estimate.inertia_matrix(axes, theta.__getitem__))
            out += [ev[0], ev[0] + ev[1] - ev[2]]
        return np.array(out)

    return checks


def _residual_rms(rows: Rows, r: np.ndarray) -> np.ndarray:
    """Rms residual per coordinate (projected residuals mapped back by the null spaces)."""
    if rows.to_coordinates is None:
        return np.array([np.sqrt(np.mean(r[rows.equation == e] ** 2)) for e in range(rows.n_eq)])
    by_time = r.reshape(-1, rows.n_eq)
    coords = np.einsum("bnr,br->bn", rows.to_coordinates, by_time)
    return np.sqrt(np.mean(coords**2, axis=0))


def _refine(model, rec: Record, fit: Fit, names: list[str]) -> Fit:
    """Every parameter in `names` refitted by simulation error: the model stepped from the
    record's states over segments of SEGMENT s with the recorded inputs, its positions
    against the record's (multiple shooting), by `scipy.optimize.least_squares`."""
    from scipy.optimize import least_squares

    system = model.compile(**fit.theta)
    h, T, n = rec.h, len(rec.t), len(model.coordinates)
    S = max(2, int(round(SEGMENT / h)))
    starts = np.arange(0, T - 1 - S, S)
    if len(starts) < 1:
        raise ValueError(f"data: too short for a simulation segment of {SEGMENT} s.")
    qd = rec.qd if rec.qd is not None else savgol_filter(rec.q, 11, POLYORDER, deriv=1,
                                                         delta=h, axis=0)  # fmt: skip
    X0 = np.hstack([rec.q[starts], qd[starts]])
    measured = np.stack([rec.q[starts + j + 1] for j in range(S)])
    scale = np.maximum(rec.q.std(0), 1e-6)
    z0 = np.array([fit.theta[k] for k in names])
    zscale = np.maximum(np.abs(z0), 1e-6)

    def residual(z):
        try:
            s = system.with_parameters(**dict(zip(names, (z * zscale).tolist())))
            x, out = X0, []
            for j in range(S):
                x = s.step(x, rec.u[starts + j], dt=h, substeps=2, t=rec.t[starts + j])
                out.append(x[:, :n])
        except ValueError:
            return np.full(measured.size, 1e3)
        return ((np.stack(out) - measured) / scale).ravel()

    sol = least_squares(residual, z0 / zscale, x_scale=1.0, method="trf")
    J = sol.jac
    dof = max(sol.fun.size - len(z0), 1)
    cov = np.linalg.pinv(J.T @ J) * (sol.fun @ sol.fun) / dof
    std = np.sqrt(np.maximum(np.diag(cov), 0.0)) * zscale
    theta = fit.theta | dict(zip(names, (sol.x * zscale).tolist()))
    return Fit(theta, fit.std | dict(zip(names, std.tolist())), fit.beta, fit.beta_std,
               fit.residual_rms, fit.condition, fit.violated)  # fmt: skip


def _result(base_model, full, setting, unknown, reg, b: estimate.Base, fit: Fit):
    lin = list(reg.linear)
    I, D, K = b.independent, b.dependent, b.K
    combos = [estimate.combination(lin, b, i) for i in range(len(I))]
    base = {}
    base_std = {}
    for i, text in enumerate(combos):
        theta_D = np.array([fit.theta[lin[d]] for d in D])
        base[text] = float(fit.theta[lin[I[i]]] + K[i] @ theta_D)
        base_std[text] = float(fit.std.get(lin[I[i]], np.nan))
    unidentifiable = {}
    for j, d in enumerate(D):
        where = [combos[i] for i in range(len(I)) if K[i, j] != 0.0]
        how = f"enters only through {'; '.join(where)}" if where else "does not enter the equations"
        unidentifiable[lin[d]] = f"{how}; held at its given value {fit.theta[lin[d]]:.6g}"
    std = {k: float(fit.std.get(k, np.nan)) for k in unknown}
    for k in unidentifiable:
        std[k] = float("nan")
    friction = {
        c: {kind: fit.theta[name] for kind, name in zip(("viscous", "coulomb"), friction_names(c))
            if name in fit.theta}
        for c in setting
    }  # fmt: skip
    parameters = {k: float(fit.theta[k]) for k in base_model.parameters}
    return Identification(
        parameters=parameters,
        std=std,
        base=base,
        base_std=base_std,
        unidentifiable=unidentifiable,
        nonlinear=tuple(reg.nonlinear),
        friction=friction,
        residual_rms=dict(zip(full.coordinates, map(float, fit.residual_rms))),
        condition=float(fit.condition),
        violated=list(fit.violated),
        unknown=tuple(unknown),
    )
