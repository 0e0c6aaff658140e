"""The one vocabulary of checks, at the bottom of the house: dynamics, envs and agents use it.

A new check of a value a user hands in belongs here when more than one floor needs it:

- `did_you_mean` and `unknown`: the one "Did you mean ...?" of every closed set of names
  (parameters, options, perturbation keys, distributions, algorithms, integrators, envs).
- `ALGORITHMS` and `INTEGRATORS`: the one table of each closed set.
- `real_array`, `real_scalar`, `finite_number`: numbers that enter. States, inputs, times,
  dt, actions and parameters must be real numbers: complex values (even with a zero
  imaginary part), booleans and strings are refused with a TypeError that names the
  argument, never silently converted; finite where it matters (ValueError naming it).
- `parameter`: 0 or of magnitude within `PARAMETER_RANGE`: the generated expressions multiply
  a few parameters together (masses, squared lengths), and within 1e-50..1e50 such products
  stay far inside the float range (about 1e-308..1e308).
- `substeps` (an integer from 1 to `MAX_SUBSTEPS`), `time_step`, `positive_float`,
  `positive_int`.
"""

from __future__ import annotations

import difflib
import math
import numbers
from collections.abc import Iterable

import numpy as np

from .methods import METHODS

PARAMETER_RANGE = (1e-50, 1e50)
"""Smallest and largest magnitude of a nonzero parameter."""

MAX_SUBSTEPS = 1_000_000
"""Most RK4 substeps per `step`: one call then costs about a second per row, and finer steps
gain nothing in double precision (RK4's error at dt / 1e6 is far below round-off)."""

ALGORITHMS = ("ppo", "sac", "td3", "tqc", "crossq")
"""The algorithms agents.train trains (stable-baselines3's; tqc and crossq from
sb3-contrib), the ones a task may name in `algo`
and `hyperparams` (a name outside this table is refused, never trained as another)."""

INTEGRATORS = tuple(METHODS)
"""The fixed-step methods `System.step` and the environments offer (dynamics.methods)."""


# ---- names ---------------------------------------------------------------------------------
def did_you_mean(name, known: Iterable, n: int = 1) -> str:
    """' Did you mean 'x'?' (or 'x' or 'y' for n > 1) for the closest of `known`, else ''."""
    close = difflib.get_close_matches(str(name), [str(k) for k in known], n=n)
    return f" Did you mean {' or '.join(map(repr, close))}?" if close else ""


def unknown(what: str, name, known: Iterable, where: str = "", n: int = 1) -> ValueError:
    """The one message of a name outside its closed set: "{where}: unknown {what} 'x'. Did
    you mean 'y'? Known: a, b." (raise it)."""
    known = [str(k) for k in known]
    head = f"{where}: unknown" if where else "Unknown"
    return ValueError(
        f"{head} {what} {name!r}.{did_you_mean(name, known, n)} Known: {', '.join(known)}."
    )


class UnknownParameterError(ValueError):
    """`name` is not a parameter of `owner` (a model), whose parameters are `known`: raised
    by `parameter_name` alone, so callers catch the type, not a message."""

    def __init__(self, name, known: Iterable, owner: str, where: str = "", options=()):
        self.name, self.known, self.owner = name, tuple(str(k) for k in known), owner
        head = f"{where}: unknown" if where else "Unknown"
        what = "argument" if options else "parameter"  # options: other names allowed there
        also = f"{', '.join(options)} and the parameters of {owner}: " if options else ""
        super().__init__(
            f"{head} {what} {name!r}{'' if options else f' of {owner}'}."
            f"{did_you_mean(name, (*self.known, *options))} Known: {also}"
            f"{', '.join(self.known)}."
        )


def parameter_name(name, known: Iterable, owner: str, where: str = "") -> str:
    """`name`, or UnknownParameterError unless it is one of `known`, the parameters of
    model `owner` (`where`: the argument or option that gave it)."""
    known = tuple(known)
    if name not in known:
        raise UnknownParameterError(name, known, owner, where)
    return name


# ---- numbers -------------------------------------------------------------------------------
def _label(owner: str, label: str) -> str:
    return f"{owner}: {label}" if owner else label


def real_array(value, label: str, owner: str = "") -> np.ndarray:
    """`value` as a float64 array; TypeError naming `label` (and `owner`, where given)
    unless it holds real numbers (booleans, complex values and text are refused); a
    ValueError naming it for ragged rows (which numpy cannot make an array of)."""
    try:
        a = np.asarray(value)
    except ValueError:
        raise ValueError(
            f"{_label(owner, label)} must be an array of numbers whose rows all have the same "
            f"length, got ragged rows {value!r:.200}."
        ) from None
    kind = a.dtype.kind
    if kind == "c":
        raise TypeError(f"{_label(owner, label)} must be real, got complex values {value!r}.")
    if kind == "b":
        raise TypeError(f"{_label(owner, label)} must be numbers, got booleans {value!r}.")
    if kind in "iuf":
        return a.astype(np.float64, copy=False)
    if kind == "O":
        try:
            return np.asarray(np.frompyfunc(_number, 1, 1)(a), dtype=np.float64)
        except (TypeError, ValueError):
            pass
    raise TypeError(f"{_label(owner, label)} must be numeric (real numbers), got {value!r:.200}.")


def _number(v) -> float:
    if isinstance(v, (str, bytes, bool, np.bool_)):
        raise TypeError(v)
    return float(v)  # TypeError for None and complex


def real_scalar(value, label: str, owner: str = "") -> float:
    """`value` as a float; TypeError naming `label` unless it is one real number."""
    if isinstance(value, (bool, np.bool_)) or np.ndim(value) != 0:
        raise TypeError(f"{_label(owner, label)} must be a real number, got {value!r:.200}.")
    return float(real_array(value, label, owner))


def finite_number(value, label: str, low: float = -math.inf, high: float = math.inf) -> float:
    """A real, finite float within [low, high] (TypeError / ValueError naming `label`)."""
    v = real_scalar(value, label)
    if not math.isfinite(v):
        raise ValueError(f"{label} must be finite, got {value!r}.")
    if not low <= v <= high:
        raise ValueError(f"{label} must be within [{low:g}, {high:g}], got {v:g}.")
    return v


def positive_float(name: str, value) -> float:
    """A positive finite real number."""
    v = real_scalar(value, name)
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}.")
    return v


def positive_int(name: str, value) -> int:
    """An integer >= 1 (booleans refused)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name} must be an integer, got {value!r}.")
    if value < 1:
        raise ValueError(f"{name} must be at least 1, got {value}.")
    return int(value)


def parameter(owner: str, name: str, value) -> float:
    """A parameter value: a finite real number, 0 or of magnitude within PARAMETER_RANGE."""
    try:
        v = real_scalar(value, f"parameter {name!r}", owner)
    except TypeError:
        raise TypeError(f"Parameter {name!r} of {owner} must be a number, got {value!r}.") from None
    if not np.isfinite(v):
        raise ValueError(f"Parameter {name!r} of {owner} must be finite, got {v}.")
    low, high = PARAMETER_RANGE
    if v != 0.0 and not low <= abs(v) <= high:
        raise ValueError(
            f"Parameter {name!r} of {owner} is out of range: |{name}| must be 0 or within "
            f"{low:g}..{high:g}, got {v:g} (products of such values would overflow)."
        )
    return v


def substeps(owner: str, value) -> int:
    """An integer number of substeps, 1..MAX_SUBSTEPS."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{owner}: substeps must be an integer, got {value!r}.")
    n = int(value)
    if not 1 <= n <= MAX_SUBSTEPS:
        raise ValueError(
            f"{owner}: substeps must be a positive integer of at most {MAX_SUBSTEPS}, got {n}."
        )
    return n


def time_step(owner: str, value) -> float:
    """dt: a positive finite real number."""
    dt = real_scalar(value, "dt", owner)
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"{owner}: dt must be a positive finite number, got {dt}.")
    return dt
