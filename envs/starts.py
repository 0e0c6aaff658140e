"""Where episodes start: a plant's start distribution, sampled, and the reset options
`state` and `goal`, checked. `envs.plant.Plant` offers these as its methods."""

from __future__ import annotations

import numpy as np

from .checks import checked_rows
from .names import start_values
from .task import resolve


def sample_start(plant, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """One starting state and goal from the task's start distribution (checked)."""
    start = plant.task.start
    if callable(start):
        return drawn_start(plant, rng)[:2]
    x = np.zeros(len(plant.state_names))
    for name, (lo, hi) in start.items():
        x[plant.state_names.index(name)] = rng.uniform(resolve(lo, plant.p), resolve(hi, plant.p))
    g = np.array([rng.uniform(lo, hi) for lo, hi in zip(plant.goal_low, plant.goal_high)])
    return x, g


def drawn_start(plant, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, bool]:
    """(x, g, named): one draw of a start function, in either form (`envs.names`), checked;
    `named` tells its form."""
    start = plant.task.start
    x, g, named = start_values(plant, start(rng, plant.p), rng)
    n_x, n_g = len(plant.state_names), len(plant.goal_names)
    if (
        x.shape != (n_x,)
        or g.shape != (n_g,)
        or not (np.isfinite(x).all() and np.isfinite(g).all())
    ):
        raise ValueError(
            f"Task {plant.task.name!r}: `start` must return a finite state of shape "
            f"({n_x},) and goal of shape ({n_g},); got {x.tolist()} and {g.tolist()}."
        )
    return x, g, named


def sample_rows(plant, k: int, outputs: bool) -> tuple[np.ndarray, np.ndarray]:
    """k starting states (a fixed seed), projected onto the constraints, with the
    declared outputs appended where `outputs`, and their goals."""
    rng = np.random.default_rng(12345)
    drawn = [sample_start(plant, rng) for _ in range(k)]
    system = plant.system
    x = np.array([d[0] for d in drawn]).reshape(k, -1)
    g = np.array([d[1] for d in drawn]).reshape(k, len(plant.goal_names))
    if system.n_c:
        x = system.project(x)
    return (with_outputs(plant, x) if outputs else x), g


def with_outputs(plant, x: np.ndarray) -> np.ndarray:
    """States x (k, 2n) with the task's declared model outputs appended: the rows the task
    functions see."""
    if not len(plant.output_index):
        return x
    k, system = len(x), plant.system
    y = system.outputs(0.0, x, np.zeros((k, system.n_u)))
    cols = [y[name] for name in plant.task.outputs]
    return np.concatenate([x, np.stack(cols, axis=-1).reshape(k, -1)], axis=1)


def check_goal(plant, g: np.ndarray) -> None:
    """ValueError unless every goal component lies in its declared range."""
    for j, name in enumerate(plant.goal_names):
        if plant.task.goal[j].angle:
            continue
        lo, hi = plant.goal_low[j], plant.goal_high[j]
        if not lo - 1e-12 * max(1.0, abs(lo)) <= g[j] <= hi + 1e-12 * max(1.0, abs(hi)):
            raise ValueError(
                f"Goal component {name!r} must lie in [{lo:.6g}, {hi:.6g}], got {g[j]:.6g}."
            )


def _given(plant, options: dict, rows, batch):
    """(states, goals) options['state'] and options['goal'] give `rows` (None where not),
    checked: shape, finite, state within the task's limits, goal within its ranges."""
    x_given = g_given = None
    if options.get("state") is not None:
        x_given = checked_rows(
            options["state"], (plant.system.state_size,), "options['state']", batch
        )[rows]
        over = np.abs(x_given) > plant.limits
        if over.any():
            i = int(np.argwhere(over)[0][1])
            raise ValueError(
                f"options['state'] component {plant.state_names[i]!r} = "
                f"{x_given[over][0]:.6g} is beyond the task's limit {plant.limits[i]:.6g}."
            )
    if options.get("goal") is not None:
        g_given = checked_rows(options["goal"], (len(plant.goal_names),), "options['goal']", batch)[
            rows
        ]
        for row in g_given:
            check_goal(plant, row)
    return x_given, g_given


def start_rows(plant, rngs, options: dict | None, rows: list[int], batch: int | None, params=None):
    """Starting states and goals of `rows`: options['state'] / options['goal'] where
    given, else drawn from the task's start distribution with each row's generator.
    Options are checked before any generator draws. Constrained models' states are
    projected onto their velocity constraints (with each row's parameters `params`,
    (len(rows), n_p), where given)."""
    system = plant.system
    options = options or {}
    if not isinstance(options, dict):
        raise TypeError(f"reset options must be a dict, got {type(options).__name__}.")
    unknown = set(options) - {"state", "goal", "params"}
    if unknown:
        raise ValueError(
            f"Unknown reset option(s) {sorted(unknown)}; known: 'state', 'goal', 'params'."
        )
    x_given, g_given = _given(plant, options, rows, batch)
    drawn = [sample_start(plant, rngs[i]) for i in rows]
    x = np.array([d[0] for d in drawn]).reshape(len(rows), system.state_size)
    g = np.array([d[1] for d in drawn]).reshape(len(rows), len(plant.goal_names))
    x = x if x_given is None else x_given
    g = g if g_given is None else g_given
    if system.n_c and params is not None:  # onto each row's own constraints
        x = np.array(
            [
                system.with_parameters(**dict(zip(system.parameters, row))).project(xi)
                for xi, row in zip(x, params)
            ]
        ).reshape(x.shape)
    elif system.n_c:
        x = system.project(x)
    return x, g
