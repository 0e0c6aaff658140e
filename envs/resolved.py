"""The parts a plant is built from, each resolved once: the env's options split from the
model's parameters, the model compiled with those parameters (`Model.compile(**params)`,
once), the parameter record the task functions read, the input limits and the stepping
options. `envs.plant.Plant.build` composes them."""

from __future__ import annotations

from collections.abc import Mapping
from functools import cache
from typing import Any

import numpy as np

import dynamics
from dynamics.checks import UnknownParameterError, did_you_mean
from dynamics.model import factory_target
from dynamics.system import method_tableau

from . import checks
from .checks import positive_float, positive_int
from .task import Task, resolve

ENV_OPTIONS = {
    "render_mode": "None, 'human' or 'rgb_array' (the vector env: 'rgb_array')",
    "control_period": "seconds per env step (default: the task's)",
    "substeps": "integrator steps per env step (default: the task's)",
    "integrator": "'dop853' or 'rk4' (default: the task's)",
    "num_threads": "threads stepping a vector env's copies (default 1; same results)",
    "max_input": "input limits: one number, or one per actuated input, each a bound or (low, high)",
    "randomize": "model parameters each copy draws, {name: (low, high)} (uniform, absolute, "
    "at every reset) or {name: distribution} (envs.randomize: uniform, log-uniform, truncated "
    "normal, choice; absolute, scale or offset; at reset, construction or every k steps); {} "
    "steps each copy with its own values, set by reset(options={'params': ...}); default "
    "None: the task's `randomize` (None there: every copy has the env's values); False: off",
    "observe_params": "True: the randomised parameters' values appended to the observation "
    "(context), bounded by their distributions' supports; or a tuple of their names "
    "(default False)",
    "perturb": "observation and action noise, motor response, delay, pushes: a dict with "
    "keys obs_noise, action_noise, motor_k, delay, push (see envs.perturb; default None: off)",
}
"""The env options besides the model's parameters (by name), with what they mean."""


def split_options(options: Mapping[str, Any] | None) -> tuple[dict, dict]:
    """(model parameters, env options) of an env's keyword arguments (`render_mode`,
    the wrapper's, dropped)."""
    params, opts = {}, {}
    for key, value in (options or {}).items():
        if key == "render_mode":
            continue
        (opts if key in ENV_OPTIONS else params)[key] = value
    return params, opts


def state_names(system) -> tuple[str, ...]:
    """Names of the state components [q, qdot]: the coordinates, then '<name>_dot'."""
    return tuple(system.coordinates) + tuple(f"{c}_dot" for c in system.coordinates)


@cache
def _model(model) -> dynamics.Model:
    if isinstance(model, str):
        return dynamics.get_model(model)
    if isinstance(model, dynamics.Model):
        return model
    if callable(model) or isinstance(model, staticmethod):
        target = factory_target(model)  # importable: keyed by its source file, and a warm
        if target is None:  # cache never rebuilds the spec (as for the registered models)
            return dynamics.Model(model)
        return dynamics.Model(target, name=target.rsplit(".", 1)[-1].split(":")[-1])
    raise TypeError(
        "A task's model must be a registered model name, a dynamics.Model, a ModelSpec "
        f"factory or a dynamics.System; got {type(model).__name__}."
    )


def compile_system(model, params: dict) -> dynamics.System:
    """The task's model compiled with `params` (`Model.compile(**params)`, once; a
    System given as the model: `with_parameters(**params)`). An unknown name is named,
    with the env options and the model's parameters it could have meant."""
    try:
        if isinstance(model, dynamics.System):
            return model.with_parameters(**params) if params else model
        return _model(model).compile(**params)
    except UnknownParameterError as exc:  # the env's options are names it could mean too
        raise UnknownParameterError(exc.name, exc.known, exc.owner, options=ENV_OPTIONS) from None


def parameter_record(task: Task, system) -> np.record:
    """The record `p` the task functions read: the system's parameters, then the task's
    `constants` (checked: names, finite numbers, no parameter shadowed). Read by name
    (`p.m1`) in Python and in numba."""
    values = dict(system.parameters)
    constants = {} if task.constants is None else task.constants(system)
    where = f"Task {task.name!r}: `constants`"
    if not isinstance(constants, Mapping):
        raise checks.DeclarationError(f"{where} must return {{name: number}}, got {constants!r}.")
    shadowed = sorted(set(constants) & set(values))
    if shadowed:
        raise checks.DeclarationError(
            f"{where} {shadowed} shadow parameters of {system.name}; the task functions "
            "would see other values than the physics. Rename them."
        )
    for k, v in constants.items():
        if not (isinstance(k, str) and k.isidentifier()):
            raise checks.DeclarationError(f"{where} name {k!r} is not an identifier.")
        try:
            values[k] = float(v)
        except (TypeError, ValueError):
            raise checks.DeclarationError(
                f"Task {task.name!r}: `constants[{k!r}]` must be a number, got {v!r}."
            ) from None
        if not np.isfinite(values[k]):
            raise checks.DeclarationError(
                f"Task {task.name!r}: `constants[{k!r}]` must be finite, got {v!r}."
            )
    dtype = [(n, np.float64) for n in values]
    records = np.rec.array([tuple(float(v) for v in values.values())], dtype=dtype)
    records.flags.writeable = False  # a record taken from a read-only array is read-only
    return records[0]


def stepping(task: Task, opts: dict) -> dict:
    """control_period, substeps, integrator and num_threads: the env's options, checked,
    else the task's."""
    get = opts.get
    period = task.control_period if get("control_period") is None else get("control_period")
    substeps = task.substeps if get("substeps") is None else get("substeps")
    integrator = task.integrator if get("integrator") is None else get("integrator")
    method_tableau(integrator)  # ValueError naming the known integrators
    threads = get("num_threads")
    return {
        "control_period": positive_float("control_period", period),
        "substeps": positive_int("substeps", substeps),
        "integrator": integrator,
        "num_threads": 1 if threads is None else positive_int("num_threads", threads),
    }


def index_of(task: Task, names: tuple[str, ...], name: str, where: str) -> int:
    """The position of state component `name` (ValueError with a suggestion)."""
    if name not in names:
        hint = did_you_mean(name, names)
        raise ValueError(
            f"Task {task.name!r}: unknown state component {name!r} in `{where}`.{hint} "
            f"Known: {', '.join(names)}."
        )
    return names.index(name)


def input_limits(value, p, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Resolved, checked (low, high) limits of the actuated inputs: each declared as a
    bound b (the range [-b, b]) or a (low, high) pair; one value serves every input."""
    if callable(value):
        value = value(p)
    if (
        isinstance(value, (str, bytes))
        or not np.ndim(value)
        and not isinstance(value, (tuple, list))
    ):
        items = [value] * n
    else:
        items = list(value)
    if any(
        isinstance(v, (bool, complex, np.complexfloating))
        for v in np.ravel(np.array(items, dtype=object))
    ):
        raise TypeError(f"max_input must be real numbers, got {value!r}.")
    if len(items) != n:
        raise ValueError(
            f"max_input must be a number or {n} numbers or (low, high) pairs, got {value!r}."
        )
    low, high = np.empty(n), np.empty(n)
    try:
        for k, v in enumerate(items):
            if isinstance(v, (tuple, list, np.ndarray)) and len(v) == 2:
                low[k], high[k] = resolve(v[0], p), resolve(v[1], p)
            else:
                high[k] = resolve(v, p)
                low[k] = -high[k]
    except (TypeError, ValueError):
        raise ValueError(
            f"max_input must be a number or {n} numbers or (low, high) pairs, got {value!r}."
        ) from None
    if not (np.isfinite(low).all() and np.isfinite(high).all() and (low < high).all()):
        raise ValueError(
            f"max_input must be positive and finite (or low < high, finite), got {value!r}."
        )
    return low, high
