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

Whether the task functions' record follows each copy's values is a fact of the plant
(`Plant.follows`, found where the plant is built: `envs.nominal`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .checks import real_array
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
        self.follows = self.randomized and plant.follows
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
        inputs = plant.constant_inputs
        moved = (values[:, inputs] != plant.randomize.nominal[inputs]).any(axis=1)
        for r in np.flatnonzero(moved).tolist():
            system = plant.system.with_parameters(**dict(zip(names, values[r].tolist())))
            for k, v in plant.task.constants(system).items():
                out[k][r] = v
    return out
