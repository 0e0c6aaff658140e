"""The distributions of `randomize=` (see `envs.randomize`): `Uniform`, `LogUniform`,
`TruncNormal` (bounds required) and `Choice`, each with how a draw applies to the nominal
value (`apply`) and when a copy draws it (`when`), and `distribution`, which reads any
declared form (a (low, high) pair, a dataclass, or a plain dict with `dist`)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields

import numpy as np
from scipy.special import ndtr, ndtri

from dynamics import checks
from dynamics.checks import did_you_mean, real_array

APPLY = ("absolute", "scale", "offset")
WHEN = ("reset", "construction")


MAX_WHEN = 2**31 - 1
"""The longest redraw interval in steps (a copy's step count is an int64; far beyond any
episode)."""


def _when(when) -> str | int:
    whole = isinstance(when, (int, np.integer)) and not isinstance(when, bool)
    if (isinstance(when, str) and when in WHEN) or (whole and 1 <= when <= MAX_WHEN):
        return int(when) if whole else when
    raise ValueError(
        f"when must be 'reset', 'construction' or a whole number of steps in 1..{MAX_WHEN}, "
        f"got {when!r:.60}.{did_you_mean(when, WHEN) if isinstance(when, str) else ''}"
    )


def _number(value, what: str) -> float:
    v = float(real_array(value, what))
    if not math.isfinite(v):
        raise ValueError(f"{what} must be finite, got {value!r}.")
    return v


class _Distribution:
    """What the distributions share: `apply`, `when`, their checks and `support`."""

    def _check(self) -> None:
        if not isinstance(self.apply, str) or self.apply not in APPLY:
            raise ValueError(
                f"apply must be one of {APPLY}, got {self.apply!r}."
                + (did_you_mean(self.apply, APPLY) if isinstance(self.apply, str) else "")
            )
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
            if not w.max() > 0:
                raise ValueError("Choice.weights must not all be 0.")
            w = w / w.max()  # (weights near the float limit would sum to inf)
            object.__setattr__(self, "weights", tuple((w / w.sum()).tolist()))
        self._check()

    def sample(self, rng) -> float:
        if self.weights is None:
            return self.values[int(rng.integers(len(self.values)))]
        return self.values[int(rng.choice(len(self.values), p=self.weights))]

    def ends(self) -> tuple[float, float]:
        return min(self.values), max(self.values)


@dataclass(frozen=True)
class Same:
    """The draw of another randomised parameter, applied to this one's nominal value:
    `{"I": Uniform(0.75, 1.25, apply="scale"), "J": Same("I")}` scales a body's moments
    by one factor, so that it stays a body (`ModelSpec.bodies`). `parameter` must be
    declared before, with a distribution of its own; `apply` and `when` are its."""

    parameter: str
    dist: Uniform | LogUniform | TruncNormal | Choice | None = None

    def __post_init__(self):
        if not isinstance(self.parameter, str):
            raise ValueError(f"Same needs a parameter name, got {self.parameter!r}.")

    @property
    def apply(self) -> str:
        return self.dist.apply

    @property
    def when(self):
        return self.dist.when

    def value(self, draw: float, nominal: float) -> float:
        return self.dist.value(draw, nominal)

    def support(self, nominal: float) -> tuple[float, float]:
        return self.dist.support(nominal)

    def ends(self) -> tuple[float, float]:
        return self.dist.ends()


DISTRIBUTIONS = {
    "uniform": Uniform,
    "loguniform": LogUniform,
    "truncnormal": TruncNormal,
    "choice": Choice,
    "same": Same,
}
"""The plain-dict form's `dist` names."""
Distribution = Uniform | LogUniform | TruncNormal | Choice | Same


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
            raise checks.unknown("dist", kind, DISTRIBUTIONS, where)
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


__all__ = [
    "APPLY",
    "DISTRIBUTIONS",
    "WHEN",
    "Choice",
    "LogUniform",
    "Same",
    "TruncNormal",
    "Uniform",
    "distribution",
]
