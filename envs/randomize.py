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

The dynamics follow each copy's values, and so does the record `p` the task functions
read (with the task's `constants` computed at the copy's values) where every function
reading it does so element by element (`warn_nominal` checks; the runtime then passes one
record per row). The task's declared numbers (input limits, bounds, goal ranges, the
start distribution) stay at the env's own values in every copy: they are constants of the
compiled step and the spaces, one for all copies; `warn_nominal` names those a
declaration touches.
`observe_params` appends the drawn values to the observation (`add_context`).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from dynamics import physical
from dynamics.checks import real_array

from .distributions import Choice, LogUniform, Same, TruncNormal, Uniform, distribution
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
        nominal = np.array(list(system.parameters.values()), dtype=np.float64)
        dists = {}
        for key, form in value.items():
            parameter_name(system, key, "randomize")
            dists[key] = d = distribution(form, key)
            if isinstance(d, Same):
                dists[key] = follow(d, key, dists)
            check_support(system, key, form, dists[key].support(nominal[names.index(key)]))
        columns = {k: names.index(k) for k in dists}
        why = physical.box_problem(system.kernels()[0], nominal, axes(dists, columns, nominal))
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


def warn_nominal(plant, rebuild) -> bool:
    """Whether the task functions' record `p` follows each copy's values (parameters and
    the `constants` computed from them): True when some task function reads `p` and every
    such function reads it element by element (checked on sample rows: given a record per
    row, each row gets what its own record gives). A warning names what stays at the
    env's values in every copy: the declared numbers (input limits, bounds, the start
    distribution) that depend on a randomised parameter, and the functions and constants
    too when they cannot follow. `rebuild(values)`: the plant with the parameters of
    `values` (name -> value) changed: one randomised parameter at an end of its range,
    together with those drawn `Same` as it."""
    spec = plant.randomize
    nudged = record_rows(plant.p, 1)[0]
    for k in plant.p.dtype.names:  # every parameter and constant moved a little
        nudged[k] = plant.p[k] * 1.001 + 1e-3
    labels, follows = _functions_reading(plant, nudged)
    follows &= bool(labels)
    changed = {}
    for name, d in spec.dists.items():
        if isinstance(d, Same):
            continue
        changed[name] = set()
        group = [name] + [k for k, f in spec.dists.items() if getattr(f, "parameter", 0) == name]
        for end in d.ends():
            other = rebuild({k: spec.dists[k].value(end, spec.nominal[spec.columns[k]])
                             for k in group})  # fmt: skip
            changed[name] |= {
                k for k in _RESOLVED if not np.array_equal(getattr(other, k), getattr(plant, k))
            }
            constants = {
                f"constant {k!r}"
                for k in plant.p.dtype.names
                if k not in plant.system.parameters and other.p[k] != plant.p[k]
            }
            drawn = [p.sample_start(np.random.default_rng(0)) for p in (plant, other)]
            if not all(np.array_equal(a, b) for a, b in zip(*drawn)):
                changed[name].add("start")
            changed[name] |= constants | _functions_reading(plant, other.p)[0]
    for name, items in changed.items():
        if follows:
            items = {k for k in items if not k.startswith(("constant", "task function"))}
        if items:
            warnings.warn(
                f"Task {plant.task.name!r}: {', '.join(sorted(items))} depend(s) on "
                f"randomised {name!r}; they keep the env's values in every copy (only the "
                "dynamics"
                + (" and the task functions' record p" if follows else "")
                + " follow each copy's parameters).",
                RuntimeWarning,
                stacklevel=5,
            )
    return follows


def _functions_reading(plant, other) -> tuple[set[str], bool]:
    """(labels, rowwise): the task functions whose values differ between `plant.p` and
    the record `other` (at sample rows with their state perturbed, so that rates are not
    all 0, and random actions), and whether each of them, given one record per row
    (alternately `plant.p` and `other`), returns row by row what that row's record gives."""
    from .names import caller, record_type  # the runtime's form of the calls

    task = plant.task
    x, g = plant.sample_rows(8)
    rng = np.random.default_rng(0)
    n_x = plant.system.state_size
    x[:, :n_x] += rng.normal(0.0, 0.5, (len(x), n_x))
    a = rng.uniform(-1.0, 1.0, (len(x), len(plant.actuated)))
    fns = [(t.name, t.fn) for t in task.terms] if task.named else [("reward", task.reward)]
    fns += [("success", task.success), ("failure", task.failure)]
    fns += [(f.name, f.fn) for f in task.observation if hasattr(f, "fn")]
    types = (record_type("Rows", plant.row_names), record_type("Actions", task.actuated),
             record_type("Goal", plant.goal_names))  # fmt: skip
    mixed = record_rows(plant.p, len(x))
    odd = np.arange(len(x)) % 2 == 1
    mixed[odd] = other
    out, rowwise = set(), True
    for label, fn in fns:
        if fn is None:
            continue
        call = caller(fn, *types) if task.named else fn
        with np.errstate(all="ignore"):
            ends = [np.asarray(call(x, a, g, p), dtype=np.float64) for p in (plant.p, other)]
            if np.array_equal(*ends, equal_nan=True):
                continue
            out.add(f"task function {label!r}")
            try:
                rows = np.asarray(call(x, a, g, mixed), dtype=np.float64)
            except Exception:  # a task function's own error: it does not read p by row
                rowwise = False
                continue
        expected = np.where(odd.reshape((-1,) + (1,) * (ends[0].ndim - 1)), *ends[::-1])
        rowwise &= rows.shape == expected.shape and np.array_equal(rows, expected, equal_nan=True)
    return out, rowwise


def record_rows(p, n: int) -> np.recarray:
    """n copies of the record `p`, one per row (read by name: `p.m1` is then (n,))."""
    rows = np.zeros(n, dtype=p.dtype).view(np.recarray)
    rows[:] = p
    return rows


def task_records(plant, values: np.ndarray) -> np.recarray:
    """The task functions' records of parameter rows `values` (k, n_p): the parameters,
    and the task's `constants` computed at each row's values where they differ from the
    env's own in a parameter the constants depend on (`constant_inputs`)."""
    names = list(plant.system.parameters)
    out = record_rows(plant.p, len(values))
    for j, k in enumerate(names):
        out[k] = values[:, j]
    if plant.task.constants is not None:
        inputs = constant_inputs(plant)
        moved = (values[:, inputs] != plant.randomize.nominal[inputs]).any(axis=1)
        for r in np.flatnonzero(moved).tolist():
            system = plant.system.with_parameters(**dict(zip(names, values[r].tolist())))
            for k, v in plant.task.constants(system).items():
                out[k][r] = v
    return out


def constant_inputs(plant) -> np.ndarray:
    """bool (n_p,): the parameters the task's `constants` depend on (each moved a little
    in turn; one the model refuses to move counts as one they depend on). Cached on the
    plant: the constants may cost a sweep of the model (CrankSlider's: 0.3 ms)."""
    cached = getattr(plant, "_constant_inputs", None)
    if cached is not None:
        return cached
    system, names = plant.system, list(plant.system.parameters)
    nominal = plant.task.constants(system)
    out = np.zeros(len(names), dtype=bool)
    for j, k in enumerate(names):
        try:
            moved = plant.task.constants(system.with_parameters(**{k: plant.p[k] * 1.001 + 1e-3}))
            out[j] = any(moved[c] != nominal[c] for c in nominal)
        except ValueError:
            out[j] = True
    plant._constant_inputs = out
    return out


__all__ = [
    "Choice",
    "LogUniform",
    "Randomization",
    "Same",
    "TruncNormal",
    "Uniform",
    "distribution",
    "draw_params",
    "redraw_due",
]
