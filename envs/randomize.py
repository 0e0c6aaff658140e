"""Domain randomisation, declared: which model parameters each copy draws, from what, how
the draw applies and when.

`randomize=` (an env option, or a `Task`'s default) maps parameter names to a
distribution, in any of these forms::

    {"m2": (0.8, 1.2)}                                   # uniform, absolute, every reset
    {"m2": Uniform(0.8, 1.2, apply="scale")}             # envs.distributions
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

`Same(name)` gives a parameter the draw of `name` (declared before it): a body's moments
scaled by one factor stay a body's. Physically impossible draws are refused when the env
is made, never redrawn: the values a declaration can reach (its support, after `apply`)
must be finite, positive (or not negative) where the model declares so, and meet the
model's conditions and give its bodies possible inertia over the whole box of supports
(`dynamics.physical.box_problem`). Each copy draws from its
own generator (the env's; copy i of a vector env: seed + i), parameters in the order
declared, so a copy reproduces a single env seeded like it.

This module declares; the runtime's parameter store (`envs.parameters.ParameterRows`)
draws, writes and redraws. The dynamics follow each copy's values, and so does the record
`p` the task functions read (with the task's `constants` computed at the copy's values)
where every function reading it does so element by element (the store checks, once per
plant; it then passes one record per row). The task's declared numbers (input limits,
bounds, goal ranges, the start distribution) stay at the env's own values in every copy:
they are constants of the compiled step and the spaces, one for all copies; the store's
nominal warning names those a declaration touches. `observe_params` appends the drawn
values to the observation (context features, `envs.observation.Context`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from dynamics import physical

from .distributions import Choice, LogUniform, Same, TruncNormal, Uniform, distribution
from .observation import Context
from .randomize_checks import axes, check_support, follow, parameter_name, whole_bodies_hint


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
        names = list(system.parameters)
        nominal = system.parameter_vector
        dists = {}
        for key, form in value.items():
            parameter_name(system, key, "randomize")
            dists[key] = d = distribution(form, key)
            if isinstance(d, Same):
                dists[key] = follow(d, key, dists)
            check_support(system, key, form, dists[key].support(nominal[names.index(key)]))
        columns = {k: names.index(k) for k in dists}
        why = physical.box_problem(system.kernel_module, nominal, axes(dists, columns, nominal))
        if why is not None:
            raise ValueError(
                f"randomize {value!r:.300} reaches impossible parameters of {system.name}: "
                f"{why}.{whole_bodies_hint(system, dists)}"
            )
        return cls(dists, columns, nominal)

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
        draws = {}
        for name in names:
            d, j = self.dists[name], self.columns[name]
            draws[name] = draws[d.parameter] if isinstance(d, Same) else d.sample(rng)
            row[j] = d.value(draws[name], self.nominal[j])


def observed(spec: Randomization | None, observe) -> tuple[Context, ...]:
    """The context features `observe` (the env option `observe_params`) asks for: True:
    every randomised parameter, in the order declared; a tuple: those named; None or
    False: none. Each is bounded by its distribution's support (the runtime clips into
    those bounds, like every feature: a value given by options['params'] may lie outside)."""
    if observe is None or observe is False:
        return ()
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
    return tuple(Context(k, spec.columns[k], *spec.support(k)) for k in names)


__all__ = [
    "Choice",
    "LogUniform",
    "Randomization",
    "Same",
    "TruncNormal",
    "Uniform",
    "distribution",
]
