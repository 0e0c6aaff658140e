"""The checks of a randomisation declaration (`envs.randomize.Randomization.declare`): names,
`Same` bound to its parameter, each range's sign and magnitude, and the box of ranges that
`dynamics.physical.box_problem` searches for an impossible plant."""

from __future__ import annotations

import numpy as np

from dynamics import checks
from dynamics.checks import did_you_mean

from .distributions import Same


def parameter_name(system, key, where: str) -> None:
    """UnknownParameterError (a ValueError, with a "Did you mean") unless `key` is a
    parameter of `system` (`dynamics.checks.parameter_name`)."""
    checks.parameter_name(key, system.parameters, system.name, where)


def follow(d: Same, key: str, dists: dict) -> Same:
    """`Same(parameter)` bound to that parameter's distribution (declared before it)."""
    leader = dists.get(d.parameter)
    if leader is None or isinstance(leader, Same) or d.parameter == key:
        raise ValueError(
            f"randomize[{key!r}] = Same({d.parameter!r}) needs {d.parameter!r} declared before "
            f"it with a distribution of its own; declared before: {', '.join(dists) or 'none'}."
            + did_you_mean(d.parameter, [k for k in dists if k != key])
        )
    return Same(d.parameter, leader)


def check_support(system, key: str, form, support: tuple[float, float]) -> None:
    """ValueError unless the values `support` of parameter `key` are finite and keep the
    parameter's declared sign (positive, or not negative)."""
    lo, hi = support
    if not (np.isfinite(lo) and np.isfinite(hi)):
        raise ValueError(f"randomize[{key!r}] = {form!r} reaches non-finite values.")
    for end in (lo, hi):  # magnitudes the generated expressions can multiply (dynamics.checks)
        try:
            checks.parameter(system.name, key, end)
        except ValueError as exc:
            raise ValueError(f"randomize[{key!r}] = {form!r}: {exc}") from None
    module = system.kernel_module
    j = list(system.parameters).index(key)
    positive = module.POSITIVE[j]
    nonnegative = getattr(module, "NONNEGATIVE", (False,) * len(module.POSITIVE))[j]
    if (positive and not lo > 0) or (nonnegative and not lo >= 0):
        sign, bound = ("positive", "> 0") if positive else ("non-negative", ">= 0")
        raise ValueError(
            f"randomize[{key!r}] = {form!r} would draw impossible values: {key} of "
            f"{system.name} must be {sign}, so low must be {bound} (the lowest value it "
            f"reaches is {lo:.6g})."
        )


def axes(dists: dict, columns: dict, nominal: np.ndarray) -> list:
    """The box of a declaration for `dynamics.physical.box_problem`: one axis per
    independent draw, moving its parameter and those declared Same as it."""
    axes = []
    for name, d in dists.items():
        if isinstance(d, Same):
            continue
        cols = [columns[name]] + [
            columns[k] for k, f in dists.items() if isinstance(f, Same) and f.parameter == name
        ]
        lo, hi = d.ends()
        axes.append(
            (
                name,
                cols,
                [d.value(lo, nominal[c]) for c in cols],
                [d.value(hi, nominal[c]) for c in cols],
            )
        )
    return axes


def whole_bodies_hint(system, dists: dict) -> str:
    """How to draw a body's inertia as a whole, where the declaration draws its moments apart."""
    for body, reads in system.bodies.items():
        apart = [k for k in reads if k in dists and not isinstance(dists[k], Same)]
        if len(apart) > 1:
            first = apart[0]
            same = ", ".join(f"{k!r}: Same({first!r})" for k in reads if k != first)
            return (
                f" Body {body!r} is drawn moment by moment; draw it as a whole, e.g. "
                f"{{{first!r}: Uniform(0.75, 1.25, apply='scale'), {same}}}."
            )
    return ""
