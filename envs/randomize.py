"""Domain randomisation, declared: which model parameters each copy draws, from what, how
the draw applies and when.

`randomize=` (an env option, or a `Task`'s default) maps parameter names to a
distribution, in any of these forms::

    {"m2": (0.8, 1.2)}                                   # uniform, absolute, every reset
    {"m2": Uniform(0.8, 1.2, apply="scale")}             # the dataclasses below
    {"m2": {"dist": "loguniform", "low": 0.5, "high": 2, "apply": "scale", "when": 100}}

Distributions: `Uniform(low, high)`, `LogUniform(low, high)` (its log uniform, low > 0),
`TruncNormal(mean, std, low, high)` (bounds required: no draw outside them) and
`Choice(values, weights=None)`. `apply`: "absolute" (the draw is the value), "scale" (the
env's own value times the draw) or "offset" (the env's own value plus the draw), always
from the env's own (nominal) value, so repeated draws never compound. `when`: "reset" (at
every reset of the copy, the default), "construction" (once per copy: at its first reset,
the env's seed being known only then, and again only at a reset given a seed, so that
`reset(seed=s)` reproduces a fresh env; autoresets and unseeded resets keep it), or an int
k (at every reset and every k steps of the copy, mid-episode).

Physically impossible draws are refused when the env is made, never redrawn: the values a
declaration can reach (its support, after `apply`) must be finite, positive for a
parameter the model declares positive, and meet the model's conditions at every corner of
the box of supports (all lows and all highs beyond 10 parameters). Each copy draws from its
own generator (the env's; copy i of a vector env: seed + i), parameters in the order
declared, so a copy reproduces a single env seeded like it.
"""

from __future__ import annotations

import difflib
import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, fields
from functools import cached_property

import numpy as np
from scipy.special import ndtr, ndtri

from .checks import real_array

APPLY = ("absolute", "scale", "offset")
WHEN = ("reset", "construction")


def _when(when) -> str | int:
    whole = isinstance(when, (int, np.integer)) and not isinstance(when, bool)
    if when in WHEN or (whole and when >= 1):
        return int(when) if whole else when
    raise ValueError(
        f"when must be 'reset', 'construction' or a whole number of steps >= 1, got {when!r}."
    )


def _number(value, what: str) -> float:
    v = float(real_array(value, what))
    if not math.isfinite(v):
        raise ValueError(f"{what} must be finite, got {value!r}.")
    return v


class _Distribution:
    """What the distributions share: `apply`, `when`, their checks and `support`."""

    def _check(self) -> None:
        if self.apply not in APPLY:
            raise ValueError(f"apply must be one of {APPLY}, got {self.apply!r}.")
        object.__setattr__(self, "when", _when(self.when))

    def value(self, draw: float, nominal: float) -> float:
        """The parameter's value for a draw, from the nominal value (never compounding)."""
        if self.apply == "scale":
            return nominal * draw
        if self.apply == "offset":
            return nominal + draw
        return draw

    def support(self, nominal: float) -> tuple[float, float]:
        """The lowest and highest value a draw gives (after `apply`)."""
        ends = [self.value(v, nominal) for v in self.ends()]
        return min(ends), max(ends)


def _ordered(self, low: str = "low", high: str = "high") -> None:
    lo = _number(getattr(self, low), f"{type(self).__name__}.{low}")
    hi = _number(getattr(self, high), f"{type(self).__name__}.{high}")
    if not lo <= hi:
        raise ValueError(f"{type(self).__name__} needs low <= high, got ({lo!r}, {hi!r}).")
    object.__setattr__(self, low, lo)
    object.__setattr__(self, high, hi)


@dataclass(frozen=True)
class Uniform(_Distribution):
    """Uniform in [low, high]."""

    low: float
    high: float
    apply: str = "absolute"
    when: str | int = "reset"

    def __post_init__(self):
        _ordered(self)
        self._check()

    def sample(self, rng) -> float:
        return rng.uniform(self.low, self.high)

    def ends(self) -> tuple[float, float]:
        return self.low, self.high


@dataclass(frozen=True)
class LogUniform(_Distribution):
    """Its logarithm uniform in [log low, log high] (0 < low <= high): every factor of the
    range as likely as any other, the usual prior for a scale."""

    low: float
    high: float
    apply: str = "absolute"
    when: str | int = "reset"

    def __post_init__(self):
        _ordered(self)
        if not self.low > 0:
            raise ValueError(f"LogUniform needs 0 < low, got low = {self.low!r}.")
        self._check()

    def sample(self, rng) -> float:
        return math.exp(rng.uniform(math.log(self.low), math.log(self.high)))

    def ends(self) -> tuple[float, float]:
        return self.low, self.high


@dataclass(frozen=True)
class TruncNormal(_Distribution):
    """Normal(mean, std) restricted to [low, high] (bounds required: a draw never leaves
    them), sampled by inverting the normal CDF over the bounds' probability interval."""

    mean: float
    std: float
    low: float
    high: float
    apply: str = "absolute"
    when: str | int = "reset"

    def __post_init__(self):
        _ordered(self)
        object.__setattr__(self, "mean", _number(self.mean, "TruncNormal.mean"))
        object.__setattr__(self, "std", _number(self.std, "TruncNormal.std"))
        if not self.std > 0:
            raise ValueError(f"TruncNormal needs std > 0, got {self.std!r}.")
        a, b = self._standard()
        if not ndtr(b) > ndtr(a):  # evaluated in the lower tail: see `_standard`
            raise ValueError(
                f"TruncNormal({self.mean!r}, {self.std!r}, {self.low!r}, {self.high!r}): "
                "the bounds hold no probability to draw from (they lie too far in a tail "
                "or are equal): give bounds nearer the mean."
            )
        self._check()

    def _standard(self) -> tuple[float, float]:
        """The bounds standardised, mirrored into the lower tail when they lie above the
        mean (where the CDF keeps its relative precision)."""
        a, b = (self.low - self.mean) / self.std, (self.high - self.mean) / self.std
        return (-b, -a) if a > 0 else (a, b)

    def sample(self, rng) -> float:
        a, b = self._standard()
        z = float(ndtri(rng.uniform(ndtr(a), ndtr(b))))
        z = -z if (self.low - self.mean) / self.std > 0 else z
        return min(max(self.mean + self.std * z, self.low), self.high)

    def ends(self) -> tuple[float, float]:
        return self.low, self.high


@dataclass(frozen=True)
class Choice(_Distribution):
    """One of `values`, with probabilities `weights` (normalised; None: equally likely)."""

    values: tuple
    weights: tuple | None = None
    apply: str = "absolute"
    when: str | int = "reset"

    def __post_init__(self):
        values = self.values
        if isinstance(values, (str, bytes, Mapping)) or not np.ndim(values) == 1 or not len(values):
            raise ValueError(f"Choice needs a non-empty sequence of numbers, got {values!r}.")
        object.__setattr__(self, "values", tuple(_number(v, "Choice.values") for v in values))
        if self.weights is not None:
            w = np.asarray(real_array(self.weights, "Choice.weights"), dtype=np.float64)
            if w.shape != (len(self.values),) or not (np.isfinite(w).all() and (w >= 0).all()):
                raise ValueError(
                    f"Choice.weights must be {len(self.values)} finite numbers >= 0, "
                    f"got {self.weights!r}."
                )
            if not w.sum() > 0:
                raise ValueError("Choice.weights must not all be 0.")
            object.__setattr__(self, "weights", tuple((w / w.sum()).tolist()))
        self._check()

    def sample(self, rng) -> float:
        if self.weights is None:
            return self.values[int(rng.integers(len(self.values)))]
        return self.values[int(rng.choice(len(self.values), p=self.weights))]

    def ends(self) -> tuple[float, float]:
        return min(self.values), max(self.values)


DISTRIBUTIONS = {
    "uniform": Uniform,
    "loguniform": LogUniform,
    "truncnormal": TruncNormal,
    "choice": Choice,
}
"""The plain-dict form's `dist` names."""
Distribution = Uniform | LogUniform | TruncNormal | Choice


def distribution(value, name: str = "") -> Distribution:
    """A distribution from any declared form: a (low, high) pair (uniform, absolute, every
    reset: the simple form), one of the dataclasses, or a dict with `dist` and its fields."""
    where = f"randomize[{name!r}]" if name else "randomize"
    if isinstance(value, Distribution):
        return value
    if isinstance(value, Mapping):
        kind = value.get("dist", "uniform")
        cls = DISTRIBUTIONS.get(kind) if isinstance(kind, str) else None
        if cls is None:
            close = difflib.get_close_matches(str(kind), list(DISTRIBUTIONS), n=1)
            hint = f" Did you mean {close[0]!r}?" if close else ""
            raise ValueError(
                f"{where}: unknown dist {kind!r}.{hint} Known: {', '.join(DISTRIBUTIONS)}."
            )
        known = [f.name for f in fields(cls)]
        unknown = sorted(set(value) - set(known) - {"dist"})
        if unknown:
            raise ValueError(f"{where}: {kind} takes {', '.join(known)}; got also {unknown}.")
        try:
            return cls(**{k: v for k, v in value.items() if k != "dist"})
        except TypeError as exc:  # a missing field
            raise ValueError(f"{where}: {exc}; {kind} takes {', '.join(known)}.") from None
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None
    if (
        isinstance(value, (str, bytes))
        or not isinstance(value, (tuple, list, np.ndarray))
        or len(value) != 2
    ):
        raise ValueError(
            f"{where} must be a (low, high) pair of numbers, a distribution (Uniform, "
            f"LogUniform, TruncNormal, Choice) or a dict with 'dist', got {value!r}."
        )
    lo, hi = (float(v) for v in real_array(value, where))
    if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
        raise ValueError(f"{where} must be finite with low <= high, got {value!r}.")
    return Uniform(lo, hi)


def parameter_name(system, key, where: str) -> None:
    """ValueError (with a "Did you mean") unless `key` is a parameter of `system`."""
    known = list(system.parameters)
    if key not in known:
        close = difflib.get_close_matches(str(key), known, n=1)
        hint = f" Did you mean {close[0]!r}?" if close else ""
        raise ValueError(
            f"{where}: {key!r} is not a parameter of {system.name}.{hint} "
            f"Known: {', '.join(known)}."
        )


@dataclass(frozen=True)
class Randomization:
    """A checked declaration on one compiled system: name -> distribution (in the order
    declared), each parameter's column in `system.parameters` and its nominal value."""

    dists: dict
    columns: dict
    nominal: np.ndarray  # (n_p,): the env's own values, in the order of system.parameters

    @classmethod
    def declare(cls, system, value) -> Randomization:
        """`value` (see the module docstring) checked against `system`: ValueError naming
        the parameter and the problem for an unknown name, a bad distribution or values
        the model refuses (not positive, or breaking its conditions at a corner)."""
        if not isinstance(value, Mapping):
            raise TypeError(
                "randomize must be a dict {parameter: (low, high) or a distribution}, got "
                f"{type(value).__name__}."
            )
        module, p = system.kernels()
        names = list(system.parameters)
        positive = dict(zip(module.PARAMETERS, module.POSITIVE))
        nominal = np.array(p.tolist(), dtype=np.float64)
        dists, supports = {}, {}
        for key, form in value.items():
            parameter_name(system, key, "randomize")
            dists[key] = d = distribution(form, key)
            lo, hi = d.support(nominal[names.index(key)])
            if not (np.isfinite(lo) and np.isfinite(hi)):
                raise ValueError(f"randomize[{key!r}] = {form!r} reaches non-finite values.")
            if positive[key] and not lo > 0:
                raise ValueError(
                    f"randomize[{key!r}] = {form!r} would draw impossible values: {key} of "
                    f"{system.name} must be positive, so low must be > 0 (the lowest value "
                    f"it reaches is {lo:.6g})."
                )
            supports[key] = (lo, hi)
        keys = list(supports)
        every = len(keys) <= 10  # every corner; beyond, all lows and all highs
        for c in range(2 ** len(keys)) if every else range(2):
            corner = {k: supports[k][(c >> j) & 1 if every else c] for j, k in enumerate(keys)}
            try:
                system.check_parameter_rows({k: [v] for k, v in corner.items()})
            except ValueError as exc:
                raise ValueError(f"randomize {value!r} reaches invalid parameters: {exc}") from None
        return cls(dists, {k: names.index(k) for k in dists}, nominal)

    def support(self, name: str) -> tuple[float, float]:
        """The values parameter `name` can take."""
        return self.dists[name].support(self.nominal[self.columns[name]])

    @cached_property
    def intervals(self) -> dict[int, list[str]]:
        """k -> the parameters redrawn every k steps."""
        out: dict[int, list[str]] = {}
        for name, d in self.dists.items():
            if isinstance(d.when, int):
                out.setdefault(d.when, []).append(name)
        return out

    def draw_into(self, rng, row: np.ndarray, names) -> None:
        """Draw the parameters `names` (in the order declared) into `row` (n_p,)."""
        for name in names:
            d, j = self.dists[name], self.columns[name]
            row[j] = d.value(d.sample(rng), self.nominal[j])


def draw_params(plant, rngs, options, rows: list[int], batch: int | None, current, first):
    """(parameters, given): the parameters (len(rows), n_p) `rows` start with, columns in
    the order of `system.parameters`, and which of them options['params'] gave (bool, the
    same shape; None without that option), or (None, None) when the plant declares no
    randomisation. For each row its declared parameters are drawn with the row's
    generator (those drawn once, at construction, only where `first`, else kept from
    `current`), then options['params'] (name -> a number for every row, or one per copy)
    where given (checked); the env's own values for the rest."""
    system, spec = plant.system, plant.randomize
    given = (options or {}).get("params") if isinstance(options, dict) else None
    if spec is None:
        if given is not None:
            raise ValueError(
                "reset option 'params' needs an env made with randomize= (e.g. "
                "randomize={} for exact values only, or {'m2': (0.8, 1.2)})."
            )
        return None, None
    names = list(system.parameters)
    values = {}
    if given is not None:
        if not isinstance(given, Mapping):
            raise TypeError(
                f"options['params'] must be a dict {{name: value}}, got {type(given).__name__}."
            )
        for key, v in given.items():
            parameter_name(system, key, "options['params']")
            v = np.asarray(real_array(v, f"options['params'][{key!r}]"), dtype=np.float64)
            if v.ndim == 0:
                v = np.full(len(rows), float(v))
            elif batch is None or v.shape != (batch,):
                raise ValueError(
                    f"options['params'][{key!r}] must be a number"
                    + (f" or an array of shape ({batch},)" if batch else "")
                    + f", got shape {v.shape}."
                )
            else:
                v = v[rows]
            values[key] = v
        if values:
            system.check_parameter_rows(values)
    out = np.tile(spec.nominal, (len(rows), 1))
    once = [k for k, d in spec.dists.items() if d.when == "construction"]
    for k, i in enumerate(rows):
        if once and not first[k]:
            for name in once:
                out[k, spec.columns[name]] = current[k, spec.columns[name]]
            spec.draw_into(rngs[i], out[k], [n for n in spec.dists if n not in once])
        else:
            spec.draw_into(rngs[i], out[k], spec.dists)
    pins = None if given is None else np.zeros(out.shape, dtype=bool)
    for name, v in values.items():
        out[:, names.index(name)] = v
        pins[:, names.index(name)] = True
    return out, pins


def redraw_due(rt, rngs, mask=None) -> None:
    """Redraw, mid-episode, the parameters declared `when=k` of the copies whose episode
    has just reached a multiple of k steps (where `mask`, bool (N,); None: every copy),
    each from its own generator, through the runtime's masked write; values given by
    options['params'] hold."""
    spec, steps = rt.plant.randomize, rt.steps
    single = len(steps) == 1  # the single env: plain ints, no arrays (a step is ~30 us)
    s = steps.item(0) if single else None
    for k, names in spec.intervals.items():
        if single:
            if s == 0 or s % k or (mask is not None and not mask[0]):
                continue
            idx = [0]
        else:
            due = (steps % k == 0) & (steps > 0)
            if mask is not None:
                due &= mask
            if not due.any():
                continue
            idx = np.flatnonzero(due).tolist()
        values = rt.P[idx]  # a copy (rows by list)
        for r, i in zip(values, idx):
            spec.draw_into(rngs[i], r, names)
        given = rt.given[idx]
        if given.any():
            values = np.where(given, rt.P[idx], values)
        rt.set_params(idx, values)


def add_context(plant, observe) -> None:
    """Append to `plant`'s observation the context features `observe` asks for (True: every
    randomised parameter, in the order declared; a tuple: those named; None or False:
    none), after the declared features, each bounded by its distribution's support. The
    runtime writes them when a copy's parameters change (clipped into those bounds, like
    every feature: a value given by options['params'] may lie outside)."""
    if observe is None or observe is False:
        return
    spec = plant.randomize
    if spec is None or not spec.dists:
        raise ValueError(
            "observe_params needs randomised parameters (randomize={name: distribution}); "
            "their distributions bound the observed values."
        )
    if observe is True:
        names = list(spec.dists)
    elif isinstance(observe, (tuple, list)) and all(isinstance(k, str) for k in observe):
        names = list(observe)
        for k in names:
            if k not in spec.dists:
                raise ValueError(
                    f"observe_params names {k!r}, which is not randomised; randomised: "
                    f"{', '.join(spec.dists)}."
                )
    else:
        raise TypeError(
            f"observe_params must be True, False or a tuple of parameter names, got {observe!r}."
        )
    context = []
    for name in names:
        lo, hi = spec.support(name)
        context.append((len(plant.columns), spec.columns[name]))
        plant.columns += ((f"param {name}", lo, hi, ""),)
        plant.obs_low = np.append(plant.obs_low, lo)
        plant.obs_high = np.append(plant.obs_high, hi)
    plant.context = np.array(context, dtype=np.int64).reshape(-1, 2)


_RESOLVED = ("input_low", "input_high", "limits", "goal_low", "goal_high", "obs_low", "obs_high",
             "term_low", "term_high")  # fmt: skip


def warn_nominal(plant, rebuild) -> None:
    """A warning naming the task's declared numbers (input limits, bounds, constants, the
    start distribution) that depend on a randomised parameter: they keep their values at
    the env's parameters in every copy (as the task functions' record `p` does), only the
    dynamics follow. `rebuild(name, value)`: the plant with one parameter changed."""
    spec = plant.randomize
    for name in spec.dists:
        changed = set()
        for end in spec.support(name):
            other = rebuild(name, end)
            changed |= {k for k in _RESOLVED if not np.array_equal(getattr(other, k),
                                                                    getattr(plant, k))}  # fmt: skip
            changed |= {
                f"constant {k!r}"
                for k in plant.p.dtype.names
                if k not in plant.system.parameters and other.p[k] != plant.p[k]
            }
            drawn = [p.sample_start(np.random.default_rng(0)) for p in (plant, other)]
            if not all(np.array_equal(a, b) for a, b in zip(*drawn)):
                changed.add("start")
        if changed:
            warnings.warn(
                f"Task {plant.task.name!r}: {', '.join(sorted(changed))} depend(s) on "
                f"randomised {name!r}; they keep the env's values in every copy (only the "
                "dynamics follow each copy's parameters).",
                RuntimeWarning,
                stacklevel=5,
            )


__all__ = [
    "Choice",
    "LogUniform",
    "Randomization",
    "TruncNormal",
    "Uniform",
    "distribution",
    "draw_params",
    "redraw_due",
]
