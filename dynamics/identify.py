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
Savitzky-Golay derivative of `q` (`scipy.signal.savgol_filter`, cubic, a `window` of
`regression.WINDOW` s unless given). A record is noisy when `noise` says so, or, without
it, when the record's own high-order differences show white noise (`regression.noise_std`,
which also gives its std; where the motion hides the noise, the result says so).

The rows (`dynamics.regression`). Unconstrained models: Lagrange's equations integrated
over windows of `span` samples (default 0.1 s), p(x_end) - p(x_start) = integral of g, the
integral by Simpson's rule on each sampling interval with the midpoint state from cubic
Hermite interpolation of (q, q') at its ends: errors of order (omega h)^4, noise-free
records fit to about 1e-7, and noise is averaged over the window, never differentiated.
Constrained models: M q'' - F at each interval's midpoint, with q'' = (q'(t1) - q'(t0)) / h,
projected on the null space of the constraint matrix B (N^T B^T lambda = 0 removes the
unknown constraint forces); a noisy record's signals, inputs too (a linear filter applied
to both sides keeps them paired), are smoothed over `regression.SMOOTH` s first
(`window=0` never smooths). Rate noise in the rows would shrink the estimates (errors in
variables): its expected second moments are computed from the rates' noise std (given, or
estimated) and removed from the normal equations.

The fit. Weighted least squares (each equation weighted by the inverse rms of its
residual in a first unweighted fit, unless that weighting lets the noise outweigh the
signal in some direction), standard errors by the Newey-West sandwich
(`estimate.hac_covariance`); when the estimates are not physical (a mass, moment or friction
coefficient below zero; a body's full inertia not positive definite or against the triangle
inequality), the fit is repeated with those constraints. Unknowns that enter nonlinearly
are held at their given values in the linear fit, then every estimated parameter is
refined by simulation error (multiple shooting over `SEGMENT` s, scipy `least_squares`).
Parameters the data cannot determine are held at their given values and listed in
`unidentifiable` with the combination they enter through; they are never estimated.
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy.signal import savgol_filter

from . import estimate, regression
from .checks import did_you_mean
from .regression import POLYORDER
from .regressor import (
    COULOMB_WIDTH,
    Regressor,
    as_model,
    catalogue,
    friction_names,
    friction_setting,
    inertial,
    with_friction,
)

SEGMENT = 0.5
"""Length (s) of a simulation-error segment (multiple shooting)."""
NOISE_DRAWS = 20
"""Copies of a noisy record refitted to measure the noise's effect on the estimates
(`_noise_spread`): the spread's own relative error is about 1 / sqrt(2 x 19), 16 % (with
12 the arm's Ibar1 came out at 1.35 % where 60 draws say 1.5-1.6 %, and a record 4 % off
was 3.5 standard errors away)."""
REL_STD = 0.25
"""Largest relative standard error of an estimate the fit writes: an unknown the record
determines worse (or one in the regressor's near-null space) is kept at its given value
and listed in `Identification.undetermined`, never written as a fitted value."""
FLAT = 1e-6
"""A singular value of the simulation error's Jacobian below this times the largest marks
a direction the record does not determine (noise-free, the arm's (m1, l1, Ibar1) family
with the first and second moments m1 l1, Ibar1 + m1 l1^2 fixed: about 1e-9)."""


@dataclass
class Identification:
    """The result of `identify` (units: the model's).

    parameters: every parameter of the model by name (unknowns at their estimates, the rest
        and the unidentifiable ones at their given values): `Model.compile(**parameters)`
        and `gym.make(env_id, **parameters)` accept it.
    std: standard error of each estimated parameter (NaN for the undetermined).
    base: the identifiable combinations (text, e.g. 'Ibar1 + 0.25*m1') and their values;
        base_std their standard errors.
    unidentifiable: {parameter: why}, the unknowns the equations do not determine.
    nonlinear: the unknowns that enter nonlinearly (refined by simulation error).
    friction: {joint: {"viscous": b, "coulomb": c}} where friction was fitted (a joint is a
        coordinate or a joint named with its rate).
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
    undetermined: dict[str, str] = field(default_factory=dict)
    """{unknown: why} for every unknown this record does not determine: those no record
    could separate (`unidentifiable`) and those this record determines worse than REL_STD;
    each is kept at its given value (`parameters`), never written as a fitted value."""
    precision: dict[str, float] = field(default_factory=dict)
    """{unknown: relative standard error} of every estimated unknown (each <= REL_STD)."""
    warnings: list[str] = field(default_factory=list)
    """What about the record makes the estimates doubtful (also issued as warnings)."""
    noise: str = ""
    """The sensors' noise the fit assumed: given, or estimated from the record (and where it
    could not be told from the motion, said so)."""
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
    friction: None, "all", or a mapping of {coordinate: kind} and {joint: (rate, kind)}
        (kind "viscous" | "coulomb" | "viscous+coulomb"; rate a linear combination of the
        coordinates' rates such as "theta2 - theta1": `regressor.friction_setting`).
    given: values of the other parameters (default the model's), and the values the
        unidentifiable and nonlinear unknowns start from.
    window: Savitzky-Golay window in samples (odd; 0: no smoothing; None: see above).
    span: samples per row of the momentum form (None: `regression.SPAN` seconds).
    width: rate scale of the smooth Coulomb term tanh(q'/width).
    refine: simulation-error refinement (None: when some unknown enters nonlinearly).
    noise: the sensors' noise std (positions, rates) where known; None estimates whether
        the noise from the record itself (`regression.noise_std`; `Identification.noise`
        says what was assumed).
    """
    base_model = as_model(model)
    setting = friction_setting(base_model, friction)
    full = with_friction(base_model, setting, width)
    cat = catalogue(full)
    names = list(cat.defaults)
    unknown = _unknown(base_model, unknown) + [
        p
        for c, (kind, _) in setting.items()
        for p, k in zip(friction_names(c), ("viscous", "coulomb"))
        if k in kind
    ]
    values = dict(cat.defaults) | _given(full, given)
    rec = regression.check_record(data, len(cat.coordinates), len(cat.inputs), noise)
    reg = Regressor(full, unknown)
    lin = list(reg.linear)
    p = np.array([values[k] for k in names])
    if lin:  # (the check reads the linear form)
        regression.check_time_base(reg, rec, p, np.array([values[k] for k in lin]))
    held: dict[str, str] = {}  # unknowns the record does not determine -> why
    if lin:
        rows = regression.build_rows(reg, rec, p, window, span)
        _check_rows(rows, rec)
        W = regression.random_regressor(reg, rec, p, seed)
        b = estimate.base(W, estimate.preference(lin, cat.units))
        spread = _noise_spread(reg, rec, p, window, span, lin, b, values, full, seed, rows.noise)
        fit = _determined_fit(rows, lin, b, values, full, spread, held)
        _refuse_unphysical(full, fit, values)
        fitted = _fitted(rows, rec, lin, b, fit)
    else:  # only unknowns that enter nonlinearly: simulation error alone
        b, fit = estimate.Base([], [], np.zeros((0, 0))), _given_fit(values, len(cat.coordinates))
        fitted, refine = {}, True
    if refine is None:
        refine = bool(reg.nonlinear)
    if refine:
        names_ = list(reg.nonlinear) + [lin[i] for i in b.independent if lin[i] not in held]
        fit = _refined(full, rec, fit, names_, values, held)
    out = _result(base_model, full, setting, unknown, reg, b, fit, held)
    out.fitted = fitted
    out.noise = rec.noise_note
    out.warnings += _record_warnings(rec, window)
    for text in out.warnings:
        warnings.warn(text, stacklevel=2)
    return out


def _given_fit(values: dict, n: int) -> Fit:
    """The start of a fit with no linear unknowns: the given values, nothing estimated."""
    return Fit(dict(values), {}, np.zeros(0), np.zeros(0), np.zeros(n), float("nan"), [])


def _determined_fit(rows, lin, b, values, full, spread: dict, held: dict) -> Fit:
    """The linear fit with every unknown the record determines worse than REL_STD held
    at its given value (added to `held` with why), worst first, each one's doubt carried
    into the rest; standard errors at least `spread` (`_noise_spread`)."""
    doubt: dict[str, float] = {}  # the held ones' variance about the given value, as seen
    while True:
        fit = _fit(rows, lin, b, values, full, doubt)
        for k, s_k in spread.items():  # the sandwich misses the noise in the regressor
            if k in fit.std:
                fit.std[k] = max(fit.std[k], s_k)
        worst = _undetermined(fit, held, values)
        if worst is None:
            return fit
        name, held[name] = worst
        doubt[name] = fit.std[name] ** 2 + (fit.theta[name] - values[name]) ** 2


def _refined(full, rec, fit: Fit, names: list[str], values: dict, held: dict) -> Fit:
    """`_refine`'s fit, with what simulation error leaves undetermined kept as given."""
    fit = _refine(full, rec, fit, names)
    for name in names:
        worst = _undetermined(Fit(fit.theta, {name: fit.std[name]}, *[None] * 5), held, values)
        if worst is not None and name not in fit.weak:
            held[name] = worst[1]
            fit.theta[name] = values[name]
    _refuse_unphysical(full, fit, values)
    return fit


def _record_warnings(rec: regression.Record, window) -> list[str]:
    """What about the record makes its estimates doubtful."""
    distortion = regression.rate_distortion(rec, window)
    if distortion <= regression.DISTORTION:
        return []
    return [
        f"positions only at {1 / rec.h:.3g} Hz: the rates derived from them change by "
        f"{distortion:.0%} between filter windows, so the motion is too fast for this "
        "sampling and the estimates are likely shrunk; record rates (qd) or sample faster"
    ]


def _noise_spread(reg, rec, p, window, span, lin, b, values, full, seed, moments) -> dict:
    """{unknown: std} of the estimates over NOISE_DRAWS copies of the record with fresh
    sensor noise of its own std added (a parametric bootstrap): the noise in the
    regressor's rates and positions, which the sandwich errors cannot see (on the arm they
    were 1.6 times too small for Ibar1). {} for a noise-free record."""
    if not regression.is_noisy(rec) or rec.sigma_qd is None and rec.qd is not None:
        return {}
    sq = rec.sigma_q if rec.sigma_q is not None else np.zeros(rec.q.shape[1])
    sqd = rec.sigma_qd if rec.sigma_qd is not None else np.zeros(rec.q.shape[1])
    if not (sq.any() or (rec.qd is not None and sqd.any())):
        return {}
    rng = np.random.default_rng(seed + 1)
    draws = []
    for _ in range(NOISE_DRAWS):
        q = rec.q + sq * rng.standard_normal(rec.q.shape)
        qd = None if rec.qd is None else rec.qd + sqd * rng.standard_normal(rec.qd.shape)
        copy = dataclasses.replace(rec, q=q, qd=qd)
        try:
            rows = regression.build_rows(reg, copy, p, window, span, moments)
            fit = _fit(rows, lin, b, values, full)
        except (ValueError, np.linalg.LinAlgError):
            continue
        draws.append([fit.theta[lin[i]] for i in b.independent])
    if len(draws) < 3:
        return {}
    spread = np.std(np.array(draws), axis=0, ddof=1)
    return {lin[i]: float(v) for i, v in zip(b.independent, spread)}


def _check_rows(rows: regression.Rows, rec: regression.Record) -> None:
    """ValueError when the record's equations overflow (values far outside the model's
    range: wrong units) or when it holds no motion the equations can see."""
    if not (np.isfinite(rows.A).all() and np.isfinite(rows.y).all()):
        raise ValueError(
            "data: the model's equations overflow on this record (values far "
            "outside its range); check that q, qd, u are in SI units."
        )
    if not np.abs(rows.A).any():
        raise ValueError(
            "data: the record does not excite the unknowns (their equations' "
            "columns are all zero); record the system under an exciting input."
        )
    if not np.abs(rows.y).max() > 1e-12 * np.abs(rows.A).max():
        raise ValueError(
            "data: nothing in the record but the unknowns does work (no input, "
            "no known force), so it tells their ratios, not their scale; record "
            "under an input, or fix one of them (given=, fewer unknown=)."
        )


def _fitted(rows: regression.Rows, rec: regression.Record, lin, b, fit) -> dict:
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
    names = list(catalogue(model).defaults)
    if unknown is None:
        unknown = inertial(model)
        if not unknown:
            raise ValueError(f"{model.name} has no inertial parameters; name the unknowns.")
    if isinstance(unknown, str):
        unknown = [unknown]
    if len(unknown) == 0:
        raise ValueError(
            "unknown: empty; name at least one parameter to fit, or None for "
            f"the inertial ones ({', '.join(inertial(model))})."
        )
    for name in unknown:
        if name not in names:
            hint = did_you_mean(str(name), names)
            raise ValueError(
                f"unknown: {model.name} has no parameter {name!r}.{hint} Known: {', '.join(names)}."
            )
    if len(set(unknown)) != len(unknown):
        raise ValueError(f"unknown: repeated names in {list(unknown)}.")
    return [n for n in names if n in unknown]  # model order


def _given(model, given) -> dict[str, float]:
    given = dict(given or {})
    for name in given:
        known = list(catalogue(model).defaults)
        if name not in known:
            hint = did_you_mean(str(name), known)
            raise ValueError(f"given: {model.name} has no parameter {name!r}.{hint}")
    out = {}
    for k, v in given.items():
        ok = isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
        if not ok or not np.isfinite(v):
            raise ValueError(f"given: {k} = {v!r}; a given value is a finite real number.")
        out[k] = float(v)
    try:
        model.compile(**out)
    except ValueError as exc:  # a sign, condition or body the model declares
        raise ValueError(f"given: {exc}") from None
    return out


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
    weak: dict = field(default_factory=dict)  # name -> why (refinement's flat directions)


def _lower(full, names: list[str], values: dict) -> dict[str, float]:
    """Lower bounds of the physical unknowns: positive parameters above 1e-9 x their given
    value (so the model still compiles), friction coefficients at 0."""
    cat = catalogue(full)
    out = {}
    for name in names:
        if name.startswith(("viscous_", "coulomb_")) and cat.units[name].startswith("force"):
            out[name] = 0.0
        elif cat.positive[name]:
            out[name] = 1e-9 * abs(values[name]) if values[name] else 1e-12
    return out


def _fit(
    rows: regression.Rows,
    lin: list[str],
    b: estimate.Base,
    values: dict,
    full,
    held: dict | None = None,
) -> Fit:
    """Weighted, noise-compensated least squares of the base parameters, the unknowns in
    `held` kept at their given values (their columns moved to the target), refitted under
    the model's physical constraints where the estimate breaks them. `held` maps each to
    the variance of its true value about the given one (what the record said of it before
    it was held): it is propagated into the others' covariance, so holding a parameter the
    record half-sees never makes their intervals narrower than the truth allows."""
    held = held or {}
    I, D, K = b.independent, b.dependent, b.K
    theta_D = np.array([values[lin[d]] for d in D])
    prior = np.array([values[lin[i]] for i in I]) + K @ theta_D  # the base values as given
    free = [j for j, i in enumerate(I) if lin[i] not in held]
    fixed = [j for j, i in enumerate(I) if lin[i] in held]
    A_I = rows.A[:, I]
    A, y = A_I[:, free], rows.y - A_I[:, fixed] @ prior[fixed]
    violated: list[str] = []

    def theta_of(beta_free):
        beta = prior.copy()
        beta[free] = beta_free
        return values | dict(zip([lin[i] for i in I], beta - K @ theta_D))

    if not free:  # everything held: nothing to fit
        r = rows.y - A_I @ prior
        return Fit(
            theta_of(np.zeros(0)),
            {},
            prior,
            np.full(len(I), np.nan),
            _residual_rms(rows, r),
            float("nan"),
            violated,
        )

    def noise(w_eq):
        if rows.noise is None:
            return None, None
        CA, cy = rows.noise
        C = CA[:, I][:, :, I]
        c = cy[:, I] - C[:, :, fixed] @ prior[fixed]  # the held columns' noise is in y now
        return (
            np.einsum("e,ekl->kl", w_eq**2, C[:, free][:, :, free]),
            np.einsum("e,ek->k", w_eq**2, c[:, free]),
        )

    R, z, gram, Aw, yw, w = _weighted(rows, A, y, noise, violated)
    beta, cond = estimate.scaled_lstsq(R, z)

    lower = _lower(full, lin, values)
    unphysical = _unphysical(full, theta_of(beta), lower)
    violated += unphysical
    if unphysical:
        lower_I = np.array([lower.get(lin[I[j]], -np.inf) for j in free]) + (K @ theta_D)[free]
        beta = estimate.constrained_fit(R, z, beta, lower_I, _body_checks(full, theta_of))
    cov = estimate.hac_covariance(Aw, yw - Aw @ beta, rows.time, rows.lag, gram)
    if fixed:  # d beta / d beta_held = -G^-1 Aw^T Aw_held, times the held ones' variance
        S = np.linalg.pinv(gram) @ (Aw.T @ (A_I[:, fixed] * w[:, None]))
        cov = cov + S @ np.diag([held[lin[I[j]]] for j in fixed]) @ S.T
    beta_std = np.full(len(I), np.nan)
    beta_std[free] = np.sqrt(np.maximum(np.diag(cov), 0.0))
    full_beta = prior.copy()
    full_beta[free] = beta
    theta = theta_of(beta)
    std = {lin[I[j]]: float(beta_std[j]) for j in free}
    r = rows.y - A_I @ full_beta
    return Fit(theta, std, full_beta, beta_std, _residual_rms(rows, r), cond, violated)


def _weighted(rows: regression.Rows, A, y, noise, violated: list[str]):
    """The normal equations `(R, z, gram)` of `A beta = y` weighted per equation by the
    inverse of its residual's spread, noise-compensated where `noise(w_eq)` allows (else
    said in `violated`), and the weighted `Aw`, `yw` and the row weights `w`."""
    ones = np.ones(rows.n_eq)
    first = estimate.compensated(A, y, *noise(ones))
    compensate = rows.noise is not None
    if first is None:  # the noise outweighs the signal in some direction: fit as it is
        violated.append(
            "the record's rate noise exceeds its signal in some direction: "
            "no errors-in-variables compensation (expect estimates shrunk)"
        )
        first = (A, y, A.T @ A)
        compensate = False
    beta, _ = estimate.scaled_lstsq(*first[:2])
    r = y - A @ beta
    sigma = np.array([np.sqrt(np.mean(r[rows.equation == e] ** 2)) for e in range(rows.n_eq)])
    w_eq = 1.0 / np.maximum(sigma, 1e-12 * sigma.max()) if sigma.max() > 0 else np.ones_like(sigma)
    Aw_, yw_ = A * w_eq[rows.equation][:, None], y * w_eq[rows.equation]
    weighted = (
        estimate.compensated(Aw_, yw_, *noise(w_eq)) if compensate else (Aw_, yw_, Aw_.T @ Aw_)
    )
    if weighted is None:  # weighting made the noise outweigh a direction: equal weights
        w_eq = ones
        weighted = first
    w = w_eq[rows.equation]
    Aw, yw = A * w[:, None], y * w
    return (*weighted, Aw, yw, w)


def _unphysical(full, theta: dict, lower: dict) -> list[str]:
    """What `theta` breaks: a lower bound, or the model's conditions and bodies."""
    from . import physical

    out = [f"{k} = {theta[k]:.6g} < {lo:g}" for k, lo in lower.items() if theta[k] < lo]
    module = catalogue(full).module
    with np.errstate(all="ignore"):
        return out + physical.problems(module, np.array([theta[k] for k in module.PARAMETERS]))


def _body_checks(full, theta_of):
    """beta -> values that must be >= 0 for the model's bodies and conditions (None when it
    declares neither): each body's smallest principal moment and the triangle inequality's
    slack, each condition's value."""
    module = catalogue(full).module
    from . import physical

    if not physical.bodies(module) and not module.CONDITIONS:
        return None

    def checks(beta):
        theta = theta_of(beta)
        pv = np.array([theta[k] for k in module.PARAMETERS])
        out = []
        for xx, xy, xz, yy, yz, zz in physical.inertias(module, pv):
            ev = np.linalg.eigvalsh(np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]))
            out += [ev[0], ev[0] + ev[1] - ev[2]]
        out += list(module.conditions(pv)) if module.CONDITIONS else []
        return np.array(out, dtype=float)

    return checks


def _refuse_unphysical(full, fit: Fit, values: dict) -> None:
    """ValueError when even the constrained fit is no possible body (never written)."""
    problems = _unphysical(full, fit.theta, _lower(full, list(fit.std), values))
    if problems:
        raise ValueError(
            "identify: no physically possible parameters fit this record (the constrained "
            f"fit still has {'; '.join(problems)}); record more, or more varied, motion."
        )


def _undetermined(fit: Fit, held: dict, values: dict) -> tuple[str, str] | None:
    """(name, why) of the estimated unknown the record determines worst, when its relative
    standard error exceeds REL_STD (or is not finite); None when every one is determined."""
    worst, rel_worst = None, REL_STD
    for name, s in fit.std.items():
        if name in held:
            continue
        value = fit.theta[name]
        rel = s / abs(value) if value != 0 else np.inf
        if not np.isfinite(rel) or rel > rel_worst:
            worst, rel_worst = name, rel
    if worst is None:
        return None
    how = f"{rel_worst:.0%}" if rel_worst < 10 else "more than 1000 %"
    why = (
        f"the record determines it only to {how} (relative standard error, above "
        f"{REL_STD:.0%}: {fit.theta[worst]:.3g} +- {fit.std[worst]:.2g}); kept at its "
        f"given value {values[worst]:.6g}"
    )
    return worst, why


def _residual_rms(rows: regression.Rows, r: np.ndarray) -> np.ndarray:
    """Rms residual per coordinate (projected residuals mapped back by the null spaces)."""
    if rows.to_coordinates is None:
        return np.array([np.sqrt(np.mean(r[rows.equation == e] ** 2)) for e in range(rows.n_eq)])
    by_time = r.reshape(-1, rows.n_eq)
    coords = np.einsum("bnr,br->bn", rows.to_coordinates, by_time)
    return np.sqrt(np.mean(coords**2, axis=0))


def _refine(model, rec: regression.Record, fit: Fit, names: list[str]) -> Fit:
    """Every parameter in `names` refitted by simulation error: the model stepped from the
    record's states over segments of SEGMENT s with the recorded inputs, its positions
    against the record's (multiple shooting), by `scipy.optimize.least_squares`."""
    from scipy.optimize import least_squares

    system = model.compile(**fit.theta)
    h, T, n = rec.h, len(rec.t), len(catalogue(model).coordinates)
    S = max(2, int(round(SEGMENT / h)))
    starts = np.arange(0, T - 1 - S, S)
    if len(starts) < 1:
        raise ValueError(f"data: too short for a simulation segment of {SEGMENT} s.")
    qd = (
        rec.qd
        if rec.qd is not None
        else savgol_filter(rec.q, 11, POLYORDER, deriv=1, delta=h, axis=0)
    )
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
    z = sol.x * zscale
    _, sv, Vt = np.linalg.svd(J, full_matrices=False)
    weak = {}
    for s_i, v in zip(sv, Vt):  # directions the simulated record does not see
        if s_i > FLAT * sv[0]:
            continue
        d = v * zscale / np.abs(v * zscale).max()  # the direction in the parameters' units
        involved = [j for j in range(len(names)) if abs(d[j]) > 0.05]
        combo = " + ".join(f"{d[j]:.3g} d{names[j]}" for j in involved)
        for j in involved:  # the start fits the record as well: kept, never moved along it
            z[j] = z0[j]
            weak[names[j]] = (
                f"the record does not change along {combo} (simulation error); held at {z0[j]:.6g}"
            )
    theta = fit.theta | dict(zip(names, z.tolist()))
    return Fit(
        theta,
        fit.std | dict(zip(names, std.tolist())),
        fit.beta,
        fit.beta_std,
        fit.residual_rms,
        fit.condition,
        fit.violated,
        weak,
    )


def _result(base_model, full, setting, unknown, reg, b: estimate.Base, fit: Fit, held: dict):
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
    unidentifiable |= fit.weak
    undetermined = unidentifiable | held
    std = {k: float(fit.std.get(k, np.nan)) for k in unknown}
    for k in undetermined:
        std[k] = float("nan")
    precision = {
        k: abs(s / fit.theta[k]) if fit.theta[k] else float("inf") for k, s in std.items() if s == s
    }
    friction = {
        c: {
            kind: float(fit.theta[name])
            for kind, name in zip(("viscous", "coulomb"), friction_names(c))
            if name in fit.theta
        }
        for c in setting
    }
    parameters = {k: float(fit.theta[k]) for k in catalogue(base_model).defaults}
    return Identification(
        parameters=parameters,
        std=std,
        base=base,
        base_std=base_std,
        unidentifiable=unidentifiable,
        nonlinear=tuple(reg.nonlinear),
        friction=friction,
        residual_rms=dict(zip(catalogue(full).coordinates, map(float, fit.residual_rms))),
        condition=float(fit.condition),
        violated=list(fit.violated),
        unknown=tuple(unknown),
        undetermined=undetermined,
        precision=precision,
    )
