"""What stays at the env's values when parameters are randomised, found once per plant
where it is built (`Plant.build`): the nominal warning (`warn`) compares the plant with
plants built at the ends of each randomised parameter's support, and names the declared
numbers (input limits, bounds, the start distribution), task functions and constants
that do not follow each copy's values; it finds whether the task functions' record can
follow them (`Plant.follows`) and which parameters the task's constants depend on
(`constant_inputs`)."""

from __future__ import annotations

import warnings

import numpy as np

from .distributions import Same
from .parameters import record_rows


def constant_inputs(plant) -> np.ndarray:
    """bool (n_p,): the parameters the task's `constants` depend on (each moved a little
    in turn; one the model refuses to move counts as one they depend on). Once per plant,
    where it is built: the constants may cost a sweep of the model (CrankSlider's: 0.3 ms)."""
    system, names = plant.system, list(plant.system.parameters)
    nominal = plant.task.constants(system)
    out = np.zeros(len(names), dtype=bool)
    for j, k in enumerate(names):
        try:
            moved = plant.task.constants(system.with_parameters(**{k: plant.p[k] * 1.001 + 1e-3}))
            out[j] = any(moved[c] != nominal[c] for c in nominal)
        except ValueError:
            out[j] = True
    return out


_RESOLVED = (
    "input_low",
    "input_high",
    "limits",
    "goal_low",
    "goal_high",
    "obs_low",
    "obs_high",
    "term_low",
    "term_high",
)


def _moved(plant, other) -> set[str]:
    """The declared numbers of `plant` that `other` (built at other values) resolves
    differently (the task's own observation columns: the context's are the supports)."""
    out = set()
    for k in _RESOLVED:
        mine, theirs = getattr(plant, k), getattr(other, k)
        if k.startswith("obs_"):
            mine = mine[: plant.observation.declared]
        if not np.array_equal(mine, theirs):
            out.add(k)
    return out


def warn(plant, at) -> bool:
    """Whether the task functions' record `p` follows each copy's values (parameters and
    the `constants` computed from them): True when some task function reads `p` and every
    such function reads it element by element (checked on sample rows: given a record per
    row, each row gets what its own record gives). A warning names what stays at the
    env's values in every copy: the declared numbers (input limits, bounds, the start
    distribution) that depend on a randomised parameter, and the functions and constants
    too when they cannot follow. `at(values)`: the plant built with the parameters
    `values` (name -> value) changed and nothing randomised, the supports compared."""
    spec = plant.randomize
    nudged = record_rows(plant.p, 1)[0]
    for k in plant.p.dtype.names:  # every parameter and constant moved a little
        nudged[k] = plant.p[k] * 1.001 + 1e-3
    labels, rowwise = _functions_reading(plant, nudged)
    rowwise &= bool(labels)
    changed = {}
    for name, d in spec.dists.items():
        if isinstance(d, Same):  # moved with the parameter it follows
            continue
        changed[name] = set()
        group = [name] + [k for k, f in spec.dists.items() if getattr(f, "parameter", 0) == name]
        for end in d.ends():  # the parameter and those drawn Same as it, at an end
            other = at({k: spec.dists[k].value(end, spec.nominal[spec.columns[k]]) for k in group})
            changed[name] |= _moved(plant, other)
            changed[name] |= {
                f"constant {k!r}"
                for k in plant.p.dtype.names
                if k not in plant.system.parameters and other.p[k] != plant.p[k]
            }
            drawn = [p.sample_start(np.random.default_rng(0)) for p in (plant, other)]
            if not all(np.array_equal(a, b) for a, b in zip(*drawn)):
                changed[name].add("start")
            changed[name] |= _functions_reading(plant, other.p)[0]
    for name, items in changed.items():
        if rowwise:
            items = {k for k in items if not k.startswith(("constant", "task function"))}
        if items:
            warnings.warn(
                f"Task {plant.task.name!r}: {', '.join(sorted(items))} depend(s) on "
                f"randomised {name!r}; they keep the env's values in every copy (only the "
                "dynamics"
                + (" and the task functions' record p" if rowwise else "")
                + " follow each copy's parameters).",
                RuntimeWarning,
                stacklevel=5,
            )
    return rowwise


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
    fns = [(t.name, t.fn) for t in task.terms]
    fns += [("success", task.success), ("failure", task.failure)]
    fns += [(f.name, f.fn) for f in task.observation if hasattr(f, "fn")]
    types = (
        record_type("Rows", plant.row_names),
        record_type("Actions", task.actuated),
        record_type("Goal", plant.goal_names),
    )
    mixed = record_rows(plant.p, len(x))
    odd = np.arange(len(x)) % 2 == 1
    mixed[odd] = other
    out, rowwise = set(), True
    for label, fn in fns:
        if fn is None:
            continue
        call = caller(fn, *types)
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
