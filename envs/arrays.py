"""The per-row arrays of a runtime's N copies, as views of three flat buffers.

Every float64 array is a view of `F`, every bool array a view of `B` (the step counts
`steps` and the float32 observation `O` stand alone), so that the fused step
(`envs.fused`) takes all of them in a few arguments. The views are made once and never
rebound: whoever holds one sees every write. The runtime writes them at a reset, its
step (`envs.step.Step`) at a step; docs/architecture.md names the writer of each.
"""

from __future__ import annotations

import numpy as np

FLOATS = (
    "X",
    "X_next",
    "U",
    "T",
    "G",
    "A",
    "obs64",
    "terms",
    "R",
    "rows_x",
    "Y",
    "steps_left",
    "E",
    "C",
)
"""The float64 arrays, in their order in `F`."""

BOOLS = ("terminated", "success", "diverged", "failed")
"""The bool arrays, in their order in `B`."""


class RowArrays:
    """The arrays of `n` rows; `widths`: the columns of each of `FLOATS` (None: one value a
    row, a 1-d array), `obs_size`: the observation's width."""

    def __init__(self, n: int, widths: tuple, obs_size: int):
        self.n, self.widths, self.obs_size = n, tuple(widths), obs_size
        width = sum(1 if w is None else w for w in self.widths)
        self.F = np.zeros(n * width)
        self.B = np.zeros(n * len(BOOLS), dtype=np.bool_)
        self.steps = np.zeros(n, dtype=np.int64)
        self.O = np.zeros((n, obs_size), dtype=np.float32)
        self._views()

    def segments(self):
        """(name, start, width or None for one value a row) of each float array in `F`,
        whose rows start..start + width (times n) it occupies."""
        start = 0
        for name, w in zip(FLOATS, self.widths):
            yield name, start, w
            start += 1 if w is None else w

    def _views(self) -> None:
        n = self.n
        for name, start, w in self.segments():
            view = self.F[n * start : n * (start + (1 if w is None else w))]
            setattr(self, name, view if w is None else view.reshape(n, w))
        for k, name in enumerate(BOOLS):
            setattr(self, name, self.B[n * k : n * (k + 1)])
        self.E0 = self.E[0]  # the first row's energy terms (the single env's info)

    # pickling: the buffers travel, the views are made again on them
    def __getstate__(self):
        return {k: getattr(self, k) for k in ("n", "widths", "obs_size", "F", "B", "steps", "O")}

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._views()


__all__ = ["BOOLS", "FLOATS", "RowArrays"]
