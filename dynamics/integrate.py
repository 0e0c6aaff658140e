"""Integrating a `System`: fixed-step RK4 (the workhorse) and scipy's DOP853 (the reference).

Inputs may be None (zero), a constant array, or a callable u(t, x) evaluated once per step of
length dt and held over it (zero-order hold, as a controller would).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.integrate import solve_ivp

from .system import System

DEFAULT_DT = 1e-3
"""Default RK4 step, s: unforced arm swings with rates up to 3 rad/s drift by at most ~1.4e-7
of their energy over 10 s at this step (2.8e-6 at 2e-3; tests/dynamics/test_integration.py)."""


def _input(u, t, x, n_u):
    if u is None:
        return np.zeros(x.shape[:-1] + (n_u,))
    if callable(u):
        return np.asarray(u(t, x), dtype=np.float64)
    return np.asarray(u, dtype=np.float64)


def simulate(
    system: System,
    x0,
    duration: float,
    dt: float = DEFAULT_DT,
    u: np.ndarray | Callable | None = None,
    substeps: int = 1,
    t0: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """RK4 from x0 over `duration` in steps of dt (each split in `substeps`).

    Returns times (K+1,) and states (K+1, ..., 2n); x0 may carry a batch axis.
    """
    steps = int(round(duration / dt))
    if steps < 1 or not np.isclose(steps * dt, duration, rtol=1e-9, atol=0):
        raise ValueError(f"duration {duration} is not a whole number of steps of {dt}.")
    x = system._state(x0).copy()
    times = t0 + dt * np.arange(steps + 1)
    states = np.empty((steps + 1,) + x.shape)
    states[0] = x
    for k in range(steps):
        uk = _input(u, times[k], x, system.n_u)
        x = system.step(x, uk, dt, substeps, times[k])
        states[k + 1] = x
    return times, states


def reference(
    system: System,
    x0,
    t_eval,
    u: np.ndarray | Callable | None = None,
    rtol: float = 1e-12,
    atol: float = 1e-12,
) -> np.ndarray:
    """DOP853 at tight tolerances from x0 (one state) through the times `t_eval`.

    A callable u(t, x) is evaluated continuously here (no zero-order hold). Returns states
    (len(t_eval), 2n). Raises RuntimeError if the solver fails.
    """
    t_eval = np.asarray(t_eval, dtype=np.float64)
    x0 = system._state(x0)

    def f(t, x):
        return system.state_derivative(t, x, _input(u, t, x, system.n_u))

    sol = solve_ivp(
        f, (t_eval[0], t_eval[-1]), x0, method="DOP853", t_eval=t_eval, rtol=rtol, atol=atol
    )
    if not sol.success:
        raise RuntimeError(f"DOP853 failed for {system.name}: {sol.message}")
    return sol.y.T
