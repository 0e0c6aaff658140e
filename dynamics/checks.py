"""Argument conversion shared by `System` and `compile`: one rule for every number that enters.

- States, inputs, times, dt and parameters must be real numbers: complex values (even with a
  zero imaginary part), booleans and strings are rejected with a TypeError that names the
  argument, never silently converted.
- They must be finite (ValueError naming the argument).
- Parameters must be 0 or of magnitude within `PARAMETER_RANGE`: the generated expressions
  multiply a few parameters together (masses, squared lengths), and within 1e-50..1e50 such
  products stay far inside the float range (about 1e-308..1e308).
- `substeps` is an integer from 1 to `MAX_SUBSTEPS`.
"""

from __future__ import annotations

import numbers

import numpy as np

PARAMETER_RANGE = (1e-50, 1e50)
"""Smallest and largest magnitude of a nonzero parameter."""

MAX_SUBSTEPS = 1_000_000
"""Most RK4 substeps per `step`: one call then costs about a second per row, and finer steps
gain nothing in double precision (RK4's error at dt / 1e6 is far below round-off)."""


def real_array(owner: str, label: str, value) -> np.ndarray:
    """`value` as a float64 array; TypeError naming `label` unless it holds real numbers."""
    a = np.asarray(value)
    kind = a.dtype.kind
    if kind == "c":
        raise TypeError(f"{owner}: {label} must be real, got complex values {value!r}.")
    if kind == "b":
        raise TypeError(f"{owner}: {label} must be numbers, got booleans {value!r}.")
    if kind in "iuf":
        return a.astype(np.float64, copy=False)
    if kind == "O":
        try:
            return np.asarray(np.frompyfunc(_number, 1, 1)(a), dtype=np.float64)
        except (TypeError, ValueError):
            pass
    raise TypeError(f"{owner}: {label} must be real numbers, got {value!r}.")


def _number(v) -> float:
    if isinstance(v, (str, bytes, bool, np.bool_)):
        raise TypeError(v)
    return float(v)  # TypeError for None and complex


def real_scalar(owner: str, label: str, value) -> float:
    """`value` as a float; TypeError naming `label` unless it is one real number."""
    if isinstance(value, (bool, np.bool_)) or np.ndim(value) != 0:
        raise TypeError(f"{owner}: {label} must be a real number, got {value!r}.")
    return float(real_array(owner, label, value))


def parameter(owner: str, name: str, value) -> float:
    """A parameter value: a finite real number, 0 or of magnitude within PARAMETER_RANGE."""
    try:
        v = real_scalar(owner, f"parameter {name!r}", value)
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
    dt = real_scalar(owner, "dt", value)
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"{owner}: dt must be a positive finite number, got {dt}.")
    return dt
