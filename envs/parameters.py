"""The model parameters of a runtime's N copies: one store, owned by the runtime.

`ParameterRows` holds everything about parameters that varies per copy, and is the only
writer of it: the nominal vector (the env's own values, `System.parameter_vector`), the
array the model's kernels read (`model_params`: the shared vector, or one row per copy
when parameters are randomised or pushes need rows), the pins (values a reset gave by
options['params'], which hold until another such reset), the once-only draws made, the
task functions' records (`task_params`: the plant's record, or one per copy when they
follow each copy's values) and the schedule of mid-episode redraws. `envs.randomize`
declares what is drawn; the store draws it (`draw`, `redraw_due`) and writes it
(`write`); the runtime hands `model_params` and `task_params` to the step, and the
perturber reads `model_params`.

The nominal warning (`follows`) runs once per plant: it names the declared numbers that
stay at the env's values in every copy, and finds whether the task functions' record can
follow each copy's values.
"""

from __future__ import annotations

import warnings
import weakref
from collections.abc import Mapping

import numpy as np

from .checks import real_array
from .distributions import Same
from .randomize import parameter_name


class ParameterRows:
    """The parameters of `n` copies of `plant` (see the module docstring); `rows`: keep
    one row per copy even without randomisation (pushes integrate with rows)."""

    def __init__(self, plant, n: int, rows: bool = False):
        self.plant, self.n, self.spec = plant, n, plant.randomize
        self.names = tuple(plant.system.parameters)
        self.nominal = plant.system.parameter_vector
        self.randomized = self.spec is not None
        self.P = np.tile(self.nominal, (n, 1)) if self.randomized or rows else None
        self.pins = np.zeros(self.P.shape, dtype=bool) if self.randomized else None
        self.drawn = np.zeros(n, dtype=bool) if self.randomized else None  # once-only draws
        self.follows = self.randomized and follows(plant)
        self.records = record_rows(plant.p, n) if self.follows else None
        self._views: dict = {}

    @property
    def model_params(self) -> np.ndarray:
        """What the model's kernels read: (n_p,) shared by every copy, or (N, n_p)."""
        return self.nominal if self.P is None else self.P

    @property
    def per_row(self) -> bool:
        return self.P is not None

    @property
    def task_params(self):
        """What the task functions read as `p`: the plant's record, or one per copy."""
        return self.plant.p if self.records is None else self.records

    def task_rows(self, rows):
        """`task_params` of `rows` only."""
        return self.plant.p if self.records is None else self.records[rows]

    # ---- drawing -------------------------------------------------------------------------
    def draw(self, rngs, options, rows: list[int], batch: int | None, seeded: bool = False):
        """(values, pins) that `rows` start an episode with, changing nothing, or None
        without randomisation: the declared parameters drawn with each row's generator
        (those drawn once only at a row's first reset or a reset given a seed, `seeded`),
        options['params'] where given (pins: which; None without that option), and the
        values given before where they still hold."""
        first = None if self.drawn is None else (self.drawn[rows] == 0) | seeded
        current = None if self.P is None else self.P[rows]
        values, pins = draw_params(self.plant, rngs, options, rows, batch, current, first)
        if values is not None and pins is None:  # the values given before still hold
            values = np.where(self.pins[rows], self.P[rows], values)
        return None if values is None else (values, pins)

    def redraw_due(self, rngs, steps: np.ndarray, mask=None) -> list[int]:
        """Redraw, mid-episode, the parameters declared `when=k` of the copies whose
        episode has just reached a multiple of k steps (where `mask`, bool (N,); None:
        every copy), each from its own generator, and write them; pinned values hold.
        The rows written."""
        if not self.randomized or not self.spec.intervals:
            return []
        single = len(steps) == 1  # the single env: plain ints, no arrays (a step is ~30 us)
        s = steps.item(0) if single else None
        written: list[int] = []
        for k, names in self.spec.intervals.items():
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
            values = self.P[idx]  # a copy (rows by list)
            for r, i in zip(values, idx):
                self.spec.draw_into(rngs[i], r, names)
            pins = self.pins[idx]
            if pins.any():
                values = np.where(pins, self.P[idx], values)
            self.write(idx, values)
            written += idx
        return written

    # ---- writing -------------------------------------------------------------------------
    def write(self, rows, values: np.ndarray, pins=None) -> None:
        """Rows `rows` step from now on with parameters `values` (len(rows), n_p), columns
        in the order of `system.parameters` (checked by `draw`); `pins`: which of them
        options['params'] gave (None: the pins stay)."""
        if not self.randomized:
            raise ValueError(
                "This runtime steps every row with the system's parameters; build its plant "
                "with randomize= (randomize={} for exact values only) for per-row values."
            )
        self.P[rows] = values
        self.drawn[rows] = True
        if pins is not None:
            self.pins[rows] = pins
        self._views = {}
        if self.records is not None:  # the task functions' records, constants recomputed
            self.records[rows] = task_records(self.plant, self.P[rows])

    def values(self, row: int | None = None) -> dict:
        """The parameter values in force: name -> float of one row, or (N,) read-only
        arrays (kept until `write`: a step's info costs no copies)."""
        if row in self._views:
            return dict(self._views[row])
        values = np.tile(self.nominal, (self.n, 1)) if self.P is None else self.P
        if row is not None:
            out = dict(zip(self.names, values[row].tolist()))
        else:
            out = {k: values[:, j].copy() for j, k in enumerate(self.names)}
            for v in out.values():
                v.flags.writeable = False
        self._views[row] = out
        return dict(out)


def draw_params(plant, rngs, options, rows: list[int], batch: int | None, current, first):
    """(values, pins): the parameters (len(rows), n_p) `rows` start with and which of them
    options['params'] gave (None without that option), or (None, None) when the plant
    declares no randomisation (see `ParameterRows.draw`)."""
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
    values = _given(system, given, rows, batch)
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


def _given(system, given, rows: list[int], batch: int | None) -> dict:
    """options['params'] checked: name -> (len(rows),) values."""
    values = {}
    if given is None:
        return values
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
    return values


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


_CONSTANT_INPUTS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_FOLLOWS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def constant_inputs(plant) -> np.ndarray:
    """bool (n_p,): the parameters the task's `constants` depend on (each moved a little
    in turn; one the model refuses to move counts as one they depend on). Once per plant:
    the constants may cost a sweep of the model (CrankSlider's: 0.3 ms)."""
    if plant in _CONSTANT_INPUTS:
        return _CONSTANT_INPUTS[plant]
    system, names = plant.system, list(plant.system.parameters)
    nominal = plant.task.constants(system)
    out = np.zeros(len(names), dtype=bool)
    for j, k in enumerate(names):
        try:
            moved = plant.task.constants(system.with_parameters(**{k: plant.p[k] * 1.001 + 1e-3}))
            out[j] = any(moved[c] != nominal[c] for c in nominal)
        except ValueError:
            out[j] = True
    _CONSTANT_INPUTS[plant] = out
    return out


def follows(plant) -> bool:
    """Whether the task functions' record `p` follows each copy's values, with the nominal
    warning (`warn_nominal`); once per plant."""
    if plant not in _FOLLOWS:
        _FOLLOWS[plant] = warn_nominal(plant)
    return _FOLLOWS[plant]


_RESOLVED = ("input_low", "input_high", "limits", "goal_low", "goal_high", "obs_low", "obs_high",
             "term_low", "term_high")  # fmt: skip


def _at(plant, values: dict):
    """`plant`'s task built with the parameters `values` (name -> value) changed (nothing
    randomised)."""
    from .plant import Plant

    options = {k: v for k, v in plant.options.items() if k not in ("observe_params", "perturb")}
    return Plant.build(plant.task, {**options, **plant.params, **values, "randomize": False})


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


def warn_nominal(plant) -> bool:
    """Whether the task functions' record `p` follows each copy's values (parameters and
    the `constants` computed from them): True when some task function reads `p` and every
    such function reads it element by element (checked on sample rows: given a record per
    row, each row gets what its own record gives). A warning names what stays at the
    env's values in every copy: the declared numbers (input limits, bounds, the start
    distribution) that depend on a randomised parameter, and the functions and constants
    too when they cannot follow."""
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
            other = _at(plant, {k: spec.dists[k].value(end, spec.nominal[spec.columns[k]])
                                for k in group})  # fmt: skip
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
                stacklevel=7,
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
    types = (record_type("Rows", plant.row_names), record_type("Actions", task.actuated),
             record_type("Goal", plant.goal_names))  # fmt: skip
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
