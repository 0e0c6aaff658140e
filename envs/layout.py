"""Former home of the bound plant: see `envs.plant` (`Layout` is now `Plant`)."""

from __future__ import annotations

import warnings

from .plant import ENV_OPTIONS, Plant, compile_model, parameter_record, state_names

Layout = Plant


def build_layout(task, params: dict, max_input=None) -> Plant:
    """Deprecated: `envs.plant.Plant.build(task, {**params, "max_input": max_input})`."""
    warnings.warn(
        "envs.layout.build_layout is now envs.plant.Plant.build.", DeprecationWarning, stacklevel=2
    )
    options = dict(params)
    if max_input is not None:
        options["max_input"] = max_input
    return Plant.build(task, options)


__all__ = [
    "ENV_OPTIONS",
    "Layout",
    "build_layout",
    "compile_model",
    "parameter_record",
    "state_names",
]
