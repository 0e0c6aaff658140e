"""Checks of configuration values (hyperparameters, planner options): each check returns
the value (numbers as int or float) or raises `Bad` saying what it must be; the caller
names the file and the key. `short` shows a value in a message, cut to a few dozen
characters (cheap on the shared structures YAML aliases build)."""

from __future__ import annotations

import math
import reprlib

_short = reprlib.Repr()
_short.maxlevel, _short.maxstring, _short.maxother = 2, 40, 40
_short.maxlist = _short.maxdict = _short.maxtuple = 4


def short(value) -> str:
    """`value`'s repr, cut to a few dozen characters (cheap on shared, aliased structures)."""
    return _short.repr(value)


class Bad(Exception):
    """What a value should have been (the caller adds the file and the key)."""


def integer(lo: int, hi: int):
    def check(v):
        if isinstance(v, float) and v.is_integer():
            v = int(v)
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise Bad(f"an integer in [{lo}, {hi}]")
        return v

    return check


def real(lo: float, hi: float, open_low: bool = False):
    def check(v):
        ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
        if not ok or not (lo < v if open_low else lo <= v) or v > hi:
            raise Bad(f"a number in {'(' if open_low else '['}{lo}, {hi}]")
        return float(v)

    return check


def schedule_of(number):
    """A number, or "lin_X" (a linear decay from X) with X such a number."""

    def check(v):
        if isinstance(v, str) and v.startswith("lin_"):
            try:
                number(float(v[4:]))
            except (ValueError, Bad) as exc:
                raise Bad(f"'lin_X' with X {exc}") from None
            return v
        try:
            return number(v)
        except Bad as exc:
            raise Bad(f"{exc} or 'lin_X'") from None

    return check


def true_or_false(v):
    if not isinstance(v, bool):
        raise Bad("true or false")
    return v


def optional(check):
    def optional(v):
        return None if v is None else check(v)

    return optional


def either(*checks):
    def check(v):
        wants = []
        for c in checks:
            try:
                return c(v)
            except Bad as exc:
                wants.append(str(exc))
        raise Bad(" or ".join(wants))

    return check


def choice(*names):
    def check(v):
        if v not in names:
            raise Bad(f"one of {', '.join(map(repr, names))}")
        return v

    return check
