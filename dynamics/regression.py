"""The regression of `dynamics.identify`: a record checked, its signals, and the rows
A theta = y built from it (the momentum form over windows for unconstrained models, the
projected acceleration form for constrained ones), with the rate noise's expected second
moments for the errors-in-variables compensation (see `dynamics.identify`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import savgol_filter

from .regressor import Regressor

WINDOW = 0.1
"""Savitzky-Golay window (s) for rates from positions when none is given."""
SMOOTH = 0.3
"""Savitzky-Golay window (s) of a noisy record's accelerations (constrained models) when
none is given: the noise of (s(t1) - s(t0)) / h falls as the window's -3/2 power; on the
rolling disk (sensor noise 1e-2 rad/s) 0.1 s left the rates' noise above the signal of
some combinations, 0.3 s fitted within 1.2 %."""
SPAN = 0.1
"""Integration window (s) of a row of the momentum form."""
NOISE_FLOOR = 1e-6
"""Estimated rate noise, over the rate's rms, above which a record is taken to be noisy
(a noise-free record's differences reach white rounding error only far below this)."""
RANDOM_STATES = 200
"""States on which the base parameters are found."""
POLYORDER = 3


ORDERS = tuple(range(2, 9))
"""Orders of the differences the noise is estimated from (`noise_std`)."""
WHITE = 0.1
"""Largest departure of the differences' robust lag-1 autocorrelation from white noise's,
-k / (k + 1) for the k-th difference, at which they are taken to be noise (`noise_std`):
a smooth motion's differences correlate positively; at 2000 samples the statistic's
sampling spread is about 0.03."""


@dataclass(frozen=True)
class Record:
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray | None
    u: np.ndarray
    h: float
    noise: tuple[float, float] | None = None
    # the sensors' noise std per channel (given or estimated), and what was done
    sigma_q: np.ndarray | None = None
    sigma_qd: np.ndarray | None = None
    noise_note: str = ""


def _mad(x: np.ndarray) -> np.ndarray:
    """Robust std per column: 1.4826 x the median absolute deviation."""
    return 1.4826 * np.median(np.abs(x - np.median(x, axis=0)), axis=0)


def with_noise(data: dict, std, seed: int = 0) -> dict:
    """A copy of the record `data` with Gaussian sensor noise of `std` = (positions, rates)
    added to q (and qd where recorded), from numpy's generator seeded with `seed`: how the
    recorder and the tests make a record as a sensor would give it."""
    rng = np.random.default_rng(seed)
    out = dict(data)
    out["q"] = data["q"] + std[0] * rng.standard_normal(np.shape(data["q"]))
    if "qd" in data:
        out["qd"] = data["qd"] + std[1] * rng.standard_normal(np.shape(data["qd"]))
    return out


def noise_std(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(std, told) per column of a sampled signal: its white measurement noise, estimated
    from its k-th differences (k in ORDERS), where a smooth motion is small, (omega h)^k,
    and white noise of std s has std s sqrt(C(2k, k)); robustly (the median absolute
    deviation, so rare fast events do not count). An order counts where its differences
    look like white noise's (lag-1 autocorrelation within WHITE of -k / (k + 1)); `told`
    is False where none does (the motion hides the noise at this sampling rate: the
    smallest estimate is then only an upper bound)."""
    cols = a.shape[1]
    best = np.full(cols, np.inf)
    bound = np.full(cols, np.inf)
    for k in ORDERS:
        if len(a) < k + 10:
            break
        d = np.diff(a, k, axis=0)
        s = _mad(d) / math.sqrt(math.comb(2 * k, k))
        plus, minus = _mad(d[1:] + d[:-1]) ** 2, _mad(d[1:] - d[:-1]) ** 2
        with np.errstate(invalid="ignore", divide="ignore"):
            r = (plus - minus) / (plus + minus)
        white = np.abs(r + k / (k + 1)) < WHITE
        best = np.where(white, np.minimum(best, s), best)
        bound = np.minimum(bound, s)
    told = np.isfinite(best)
    return np.where(told, best, bound), told


def _noise(q, qd, noise) -> tuple[np.ndarray, np.ndarray | None, str]:
    """(sigma_q, sigma_qd, note): the given noise, or the record's estimate (`noise_std`)
    where it can be told from the motion and 0 (no compensation) where it cannot."""
    n = q.shape[1]
    if noise is not None:
        return np.full(n, noise[0]), np.full(n, noise[1]), f"given: std {noise[0]:g}, {noise[1]:g}"
    signal = qd if qd is not None else q
    s, told = noise_std(signal)
    kind = "rates" if qd is not None else "positions"
    note = f"estimated from the record's {kind}: std " + ", ".join(f"{v:.3g}" for v in s)
    if not told.all():
        which = ", ".join(str(i) for i in np.flatnonzero(~told))
        note += (
            f"; for coordinate(s) {which} the motion hides the noise at this sampling "
            "rate (the figure is only an upper bound): not compensated there, so those "
            "estimates may be shrunk; give noise= (--noise) if you know it"
        )
        s = np.where(told, s, 0.0)
    if qd is not None:
        sq, _ = noise_std(q)
        return sq, s, note
    return s, None, note


MAX_STEP = 1.0
"""Largest sampling step (s) of a record: slower sampling sees none of a mechanical
system's dynamics (the model's own time scale is checked by `identify`)."""
HUGE = 1e9
"""Largest magnitude a record's value may have (SI units: positions in rad or m, rates,
inputs in N or N*m); larger is a unit or file error, and overflows the equations."""


def _real(value, key: str) -> np.ndarray:
    """data[key] as a float array; ValueError (one line) unless it holds real numbers."""
    a = np.asarray(value)
    if a.dtype.kind not in "iuf":
        what = {
            "c": "complex numbers",
            "b": "booleans",
            "U": "text",
            "S": "bytes",
            "O": "objects",
        }.get(a.dtype.kind, f"dtype {a.dtype}")
        raise ValueError(f"data[{key!r}]: {what} ({a.dtype}); a record holds real numbers.")
    return a.astype(float)


def check_record(data, n: int, nu: int, noise=None) -> Record:
    """The record's arrays, checked: shapes, finite values, uniform sampling."""
    if not hasattr(data, "__getitem__") or not hasattr(data, "keys"):
        raise TypeError(f"data must be a mapping with t, q, [qd,] u; got {type(data).__name__}.")
    missing = [k for k in ("t", "q", "u") if k not in data.keys()]
    if missing:
        raise ValueError(f"data: missing {', '.join(missing)} (needs t, q, [qd,] u).")
    t = _real(data["t"], "t")
    if t.ndim != 1 or len(t) < 20:
        raise ValueError(f"data['t']: expected at least 20 samples in one axis, got {t.shape}.")
    T = len(t)
    arrays = {"q": (T, n), "u": (T, nu)} | ({"qd": (T, n)} if "qd" in data.keys() else {})
    got = {}
    for key, shape in arrays.items():
        a = _real(data[key], key)
        if a.ndim == 1 and shape[1] == 1:
            a = a[:, None]
        if a.shape != shape:
            raise ValueError(f"data[{key!r}]: expected shape {shape}, got {a.shape}.")
        got[key] = a
    for key, a in [("t", t), *got.items()]:
        bad = ~np.isfinite(a)
        if bad.any():
            where = np.argwhere(bad)[0]
            raise ValueError(
                f"data[{key!r}]: {a[tuple(where)]} at {tuple(where.tolist())}; "
                "a record holds finite numbers only."
            )
        big = float(np.abs(a).max())
        if big > HUGE:
            raise ValueError(
                f"data[{key!r}]: a value of magnitude {big:.3g}; a record's values "
                f"are SI quantities below {HUGE:g} (check the units)."
            )
    still = np.ptp(got["q"], axis=0).max() == 0 and ("qd" not in got or not np.abs(got["qd"]).any())
    if still:
        raise ValueError(
            "data: the record does not move (every q constant): it cannot tell "
            "any parameter; record the system under an exciting input."
        )
    dt = np.diff(t)
    h = float(np.mean(dt))
    if not h > 0 or np.abs(dt - h).max() > 1e-6 * h:
        raise ValueError("data['t'] must be increasing with a uniform step (resample first).")
    if h > MAX_STEP:
        raise ValueError(
            f"data['t']: a step of {h:g} s; a record's time is in seconds and "
            f"its step at most {MAX_STEP:g} s (milliseconds given as seconds?)."
        )
    given = noise
    if noise is not None:
        try:
            noise = tuple(float(v) for v in noise)
        except (TypeError, ValueError):
            noise = ()
        if len(noise) != 2 or not all(v >= 0 and math.isfinite(v) for v in noise):
            raise ValueError(f"noise: two stds >= 0 (positions, rates) or None, got {given!r}.")
    sigma_q, sigma_qd, note = _noise(got["q"], got.get("qd"), noise)
    return Record(t, got["q"], got.get("qd"), got["u"], h, noise, sigma_q, sigma_qd, note)


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


def is_noisy(rec: Record) -> bool:
    """Whether the record carries measurement noise: as given, or where the estimate
    (`noise_std`) is above NOISE_FLOOR of a signal's rms."""
    if rec.qd is None:
        return True
    if rec.noise is not None:
        return max(rec.noise) > 0
    rms = np.sqrt(np.mean(rec.qd**2, axis=0))
    return bool(np.any(rec.sigma_qd > NOISE_FLOOR * rms))


def signals(rec: Record, window: int | None, constrained: bool) -> tuple:
    """(q, qd, u, window used, noisy): the signals the rows are built from."""
    h, noisy = rec.h, is_noisy(rec)
    default = max(2 * int(round(WINDOW / h / 2)) + 1, POLYORDER + 2 + (POLYORDER % 2))
    if window is not None and window != 0 and (window % 2 == 0 or window <= POLYORDER):
        raise ValueError(
            f"window must be 0 or an odd number of samples > {POLYORDER}, got {window}."
        )
    if rec.qd is None:  # rates by the filter's derivative; accelerations smooth the rest too
        w = window or default
        qd = savgol_filter(rec.q, w, POLYORDER, deriv=1, delta=h, axis=0)
        if not constrained:
            return rec.q, qd, rec.u, w, noisy
        q = savgol_filter(rec.q, w, POLYORDER, axis=0)
        return q, qd, savgol_filter(rec.u, w, POLYORDER, axis=0), w, noisy
    if window is None:  # the momentum form averages noise itself; accelerations need it
        smooth = max(2 * int(round(SMOOTH / h / 2)) + 1, POLYORDER + 2 + (POLYORDER % 2))
        window = smooth if (noisy and constrained) else 0
    if window == 0:
        return rec.q, rec.qd, rec.u, 0, noisy
    smooth = [savgol_filter(a, window, POLYORDER, axis=0) for a in (rec.q, rec.qd, rec.u)]
    return *smooth, window, noisy


def midpoints(q, qd, h, hermite: bool):
    """States at the intervals' midpoints: cubic Hermite from both ends (rates by its
    derivative where the record is exact; where it is noisy, which that derivative would
    amplify, by the cubic through the four nearest rates)."""
    qm = (q[:-1] + q[1:]) / 2 + h * (qd[:-1] - qd[1:]) / 8
    if hermite:
        qdm = 1.5 * (q[1:] - q[:-1]) / h - (qd[:-1] + qd[1:]) / 4
    else:  # cubic through four rates (error of order h^4 where the mean's is h^2, whose
        # bias on a fast motion was -0.45 % of the arm's Ibar2: 4 standard errors)
        qdm = (qd[:-1] + qd[1:]) / 2
        if len(qd) >= 4:
            qdm[1:-1] = (9 * (qd[1:-2] + qd[2:-1]) - qd[:-3] - qd[3:]) / 16
    return np.hstack([qm, qdm])


def build_rows(reg: Regressor, rec: Record, p, window, span, moments=None) -> Rows:
    """The rows of `rec`; `moments`: the noise's second moments to use instead of
    computing them (a refit of the same record with other noise draws)."""
    constrained = reg._m.N_C > 0
    q, qd, u, w, noisy = signals(rec, window, constrained)
    h, t = rec.h, rec.t
    X = np.hstack([q, qd])
    mid = midpoints(q, qd, h, hermite=not noisy and w == 0)
    lag = int(np.ceil(w / max(span or 1, 1))) + 1
    if constrained:
        qdd = (qd[1:] - qd[:-1]) / h
        rows = acceleration_rows(reg, t[:-1] + h / 2, mid, qdd, u[:-1], p, w)
        if noisy and rec.qd is not None:
            rows.noise = moments or acceleration_noise(
                reg, rec, t[:-1] + h / 2, mid, qdd, u[:-1], p, w
            )
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
    compensate = noisy and (w == 0 or rec.qd is None)
    noise = (moments or rate_noise(reg, rec, t, X, u, p, ends, L * h, w)) if compensate else None
    return Rows(A.reshape(-1, nk), y.reshape(-1), eq, time, lag, None, n, noise)


def rate_noise(reg, rec: Record, t, X, u, p, ends, span_s, w: int = 0):
    """Second moments of the rate noise in the momentum rows, for bias compensation.

    A row's regressor and target hold the momenta at the window's ends, which are linear in
    the measured rates: noise n of std sigma_i in rate i puts J_i n into the row
    (J_i = dP/dqd_i, and dp0/dqd_i in the target), so least squares on noisy rows
    converges to (A^T A + E[N^T N])^-1 (A^T y + E[N^T e]), shrunk towards zero (errors in
    variables). The fit subtracts these expectations. The positions' noise moves the
    momenta through M(q) (with the arm moving at 10 rad/s, 1e-3 rad of it did as much as
    1e-2 rad/s of rate noise, and biased Ibar1 by 4 standard errors): its Jacobian, by
    central differences, enters the same way. The stds are `Record.sigma_q`, `sigma_qd`."""
    n = reg.n_q
    sigma = rate_sigma(rec, w)
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
    sigma_q = rec.sigma_q if rec.sigma_q is not None else np.zeros(n)
    for i in range(n):  # position noise moves the momenta too (M(q) q'): by its Jacobian
        if not sigma_q[i] > 0:
            continue
        step = 1e-6 * max(1.0, float(np.abs(Xe[:, i]).max()))
        Xp, Xm = Xe.copy(), Xe.copy()
        Xp[:, i] += step
        Xm[:, i] -= step
        (Pp, pp0, _, _), (Pm, pm0, _, _) = reg.momentum(te, Xp, ue, p), reg.momentum(te, Xm, ue, p)
        J, j0 = (Pp - Pm) / (2 * step * span_s), -(pp0 - pm0) / (2 * step * span_s)
        for sl in both:
            CA += sigma_q[i] ** 2 * np.einsum("bek,bel->ekl", J[sl], J[sl])
            cy += sigma_q[i] ** 2 * np.einsum("bek,be->ek", J[sl], j0[sl])
    return CA, cy


def rate_sigma(rec: Record, w: int = 0) -> np.ndarray:
    """The rates' noise std (given, or estimated: `Record.sigma_qd`). Without recorded
    rates, those of the filter's derivative (window w) of positions with noise sigma_q:
    sigma_q sqrt(sum d_j^2) / h, d its weights."""
    from scipy.signal import savgol_coeffs

    if rec.qd is not None:
        return rec.sigma_qd
    d = savgol_coeffs(w, POLYORDER, deriv=1)
    return rec.sigma_q * np.sqrt(np.sum(d**2)) / rec.h


def acceleration_noise(reg, rec: Record, T, X, QDD, U, p, w: int):
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
    sigma2 = rate_sigma(rec) ** 2
    var_qdd = sigma2 * np.sum(np.diff(padded) ** 2) / rec.h**2
    var_qd = sigma2 * np.sum(((padded[1:] + padded[:-1]) / 2) ** 2)
    n = reg.n_q
    B, _, _ = reg.constraints(T, X, p)
    Nsp = null_spaces(B)

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


def null_spaces(B: np.ndarray) -> np.ndarray:
    """(N, n, n - m): orthonormal bases of the null spaces of B (N, m, n)."""
    m = B.shape[1]
    _, _, Vt = np.linalg.svd(B)
    return np.swapaxes(Vt[:, m:, :], 1, 2)


def acceleration_rows(reg, T, X, QDD, U, p, w) -> Rows:
    Y, y0 = reg.acceleration(T, X, QDD, U, p)
    B, _, _ = reg.constraints(T, X, p)
    Nsp = null_spaces(B)
    A = np.einsum("bnr,bnk->brk", Nsp, Y)
    y = -np.einsum("bnr,bn->br", Nsp, y0)
    times, r = A.shape[0], A.shape[1]
    eq = np.tile(np.arange(r), times)
    time = np.repeat(np.arange(times), r)
    return Rows(A.reshape(-1, A.shape[2]), y.reshape(-1), eq, time, max(w, 1), Nsp, r)


def random_regressor(reg: Regressor, rec: Record, p, seed: int) -> np.ndarray:
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
        Nsp = null_spaces(B)
        qd = np.einsum("bnr,bmr,bm->bn", Nsp, Nsp, qd)
        qd -= np.einsum("bnm,bm->bn", np.linalg.pinv(B), b)
        B, _, gamma = reg.constraints(T, np.hstack([q, qd]), p)
        qdd = np.einsum("bnr,bmr,bm->bn", Nsp, Nsp, qdd)
        qdd += np.einsum("bnm,bm->bn", np.linalg.pinv(B), gamma)
    rows = acceleration_rows(reg, T, np.hstack([q, qd]), qdd, U, p, 1)
    return rows.A


TIME_SCALE = 100.0
"""Largest ratio between the record's accelerations and the model's at the same states and
inputs (either way) before the record's time base or units are refused: a model with its
parameters off by the factors identification corrects (a few) stays far inside it, a time
base off by a thousand (milliseconds) far outside."""


def check_time_base(reg: Regressor, rec: Record, p, theta) -> None:
    """ValueError when the record's accelerations and the model's differ by more than
    TIME_SCALE: the rms of N^T M q'' (the record's accelerations, projected off the
    constraint forces) against that of N^T F (the model's forces at the record's states
    and inputs, `p` and `theta` its parameters), equal for a record of the model. Off by
    a million: time not in seconds, or values not in the model's units."""
    h = rec.h
    w = max(2 * int(round(WINDOW / h / 2)) + 1, POLYORDER + 2 + (POLYORDER % 2))
    w = min(w, (len(rec.t) - 2) // 2 * 2 + 1)  # a record shorter than the window: all of it
    qd = (
        rec.qd
        if rec.qd is not None
        else savgol_filter(rec.q, w, POLYORDER, deriv=1, delta=h, axis=0)
    )
    qdd = savgol_filter(qd, w, POLYORDER, deriv=1, delta=h, axis=0)
    X = np.hstack([rec.q, qd])
    with np.errstate(all="ignore"):
        moved = acceleration_rows(reg, rec.t, X, qdd, rec.u, p, 1)
        still = acceleration_rows(reg, rec.t, X, np.zeros_like(qdd), rec.u, p, 1)
        inertia = (moved.A - still.A) @ theta - (moved.y - still.y)  # N^T M q''
        force = still.y - still.A @ theta  # N^T F
        a, b = np.sqrt(np.mean(inertia**2)), np.sqrt(np.mean(force**2))
    if not (np.isfinite(a) and np.isfinite(b)) or a == 0 or b == 0:
        return
    ratio = a / b
    if ratio > TIME_SCALE or ratio < 1 / TIME_SCALE:
        raise ValueError(
            f"data['t']: with a step of {h:g} s the record's accelerations are {ratio:.3g} "
            f"times the model's at the same states and inputs; t must be in seconds and q, "
            f"qd, u in the model's SI units (milliseconds given as seconds?)."
        )


DISTORTION = 0.02
"""Relative rms difference of positions-only rates between the cubic filter used and a
quintic one (beyond what noise explains) above which the record is warned as sampled too
slowly for its motion (the arm: 0.1-1.7 % where the fit was within 6 %, 2.2 % where it was
7-14 % low, 12-25 % at 20 Hz)."""


def rate_distortion(rec: Record, window: int | None) -> float:
    """For a positions-only record: the relative rms difference between the rates of the
    cubic Savitzky-Golay filter used and those of a quintic one (less biased on a fast
    motion) over at least 7 samples, less its share from the positions' noise; 0 when rates
    are recorded. A fast motion sampled slowly is flattened by the cubic filter (at 20 Hz
    the arm's inertias came out 24-59 % low)."""
    from scipy.signal import savgol_coeffs

    if rec.qd is not None:
        return 0.0
    h = rec.h
    w = window or max(2 * int(round(WINDOW / h / 2)) + 1, POLYORDER + 2 + (POLYORDER % 2))
    ref = max(w, 7)
    if len(rec.t) <= ref:
        return 0.0
    used = savgol_filter(rec.q, w, POLYORDER, deriv=1, delta=h, axis=0)
    quintic = savgol_filter(rec.q, ref, 5, deriv=1, delta=h, axis=0)
    c_used = np.zeros(ref)
    pad = (ref - w) // 2
    c_used[pad : pad + w] = savgol_coeffs(w, POLYORDER, deriv=1)
    noise = rec.sigma_q * np.sqrt(np.sum((c_used - savgol_coeffs(ref, 5, deriv=1)) ** 2)) / h
    change = np.sqrt(np.maximum(np.mean((used - quintic) ** 2, 0) - noise**2, 0.0))
    scale = np.sqrt(np.mean(quintic**2, 0))
    return float(np.max(change / np.maximum(scale, 1e-300)))
