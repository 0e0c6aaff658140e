"""The start region a task declares for LQR (`LQRHints.region`), checked at make against the
task's limits and failure function."""

from __future__ import annotations

import numpy as np

from .checks import declaration_error
from .starts import sample_rows, with_outputs


def check_region(plant, label: str, failure) -> None:
    """The start region the task declares for LQR (`lqr.region`) stays inside the limits
    and outside the failure set: the operating point of a sample goal moved by each
    half-width alone, either way, is tried (else LQR's score counts starts that fail at
    once, e.g. a ball placed past the beam's end, and gives no reason)."""
    task = plant.task
    region = dict(task.lqr.region or {})
    if not region or task.operating_point is None:
        return
    names = plant.state_names
    rows, g = sample_rows(plant, 1, outputs=False)
    try:
        with np.errstate(all="ignore"):
            x0 = plant.operating_state(g, rows)[0]
    except Exception:  # the operating point's own slips are named by _check_operating_point
        return
    moves = [(k, sign * float(plant.resolve(w))) for k, w in region.items() for sign in (1, -1)]
    x = np.tile(x0, (len(moves), 1))
    for row, (k, step) in enumerate(moves):
        x[row, names.index(k)] += step
    beyond = np.abs(x) > plant.limits
    if beyond.any():
        row, i = (int(v) for v in np.argwhere(beyond)[0])
        raise declaration_error(
            task.name,
            f"lqr.region[{moves[row][0]!r}]",
            f"= {abs(moves[row][1]):.6g} about the operating point reaches {names[i]} = "
            f"{x[row, i]:.6g}, beyond `limits[{names[i]!r}]` = {plant.limits[i]:.6g}.",
        )
    full = with_outputs(plant, x)
    a = np.zeros((len(x), len(plant.actuated)))
    with np.errstate(all="ignore"):
        failed = np.asarray(failure(full, a, np.repeat(g, len(x), axis=0), plant.p), dtype=bool)
    if failed.any():
        row = int(np.argmax(failed))
        k, step = moves[row]
        raise declaration_error(
            task.name,
            f"lqr.region[{k!r}]",
            f"= {abs(step):.6g} reaches into the failure set: the operating point with {k} "
            f"{'+' if step > 0 else '-'}{abs(step):.6g} ({k} = {x[row, names.index(k)]:.6g}) "
            f"fails by {label} at once; make the region smaller than the failure bound.",
        )
