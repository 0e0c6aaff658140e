"""Exciting inputs for identification: periodic multisines within the input limits.

Each input j gets its own harmonics of the base frequency 1/period (input j takes every
n_u-th harmonic, starting at its own, so no two inputs share a frequency and their
contributions are uncorrelated over a period), with Schroeder's phases (a low crest
factor: the largest value is close to the rms times sqrt(2), so the limit is used well).
Amplitudes fall as 1/k, so the low harmonics, which move the system most, dominate; the
sum is scaled so that its peak is `fraction` of each input's limit. A smooth signal keeps
the record's accelerations continuous within each sampling interval, which is what the
regression's interpolation assumes (`dynamics.identify`).
"""

from __future__ import annotations

import numpy as np


def multisine(
    limits,
    period: float = 10.0,
    harmonics: int = 6,
    fraction: float = 0.5,
    seed: int = 0,
):
    """A function t -> u (n_u,) (or (T, n_u) for t (T,)), periodic in `period` s.

    limits: (n_u,) the inputs' magnitude limits (inputs that must stay zero: 0).
    harmonics: sinusoids per input; the highest frequency is about
        n_u x harmonics / period.
    fraction: the peak of each input over its limit, in (0, 1]."""
    limits = np.atleast_1d(np.asarray(limits, dtype=float))
    if not np.isfinite(limits).all() or (limits < 0).any():
        raise ValueError(f"limits must be finite and >= 0, got {limits}.")
    if not 0 < fraction <= 1:
        raise ValueError(f"fraction must be in (0, 1], got {fraction}.")
    if not period > 0 or int(harmonics) < 1:
        raise ValueError(f"period must be > 0 and harmonics >= 1, got {period}, {harmonics}.")
    nu = len(limits)
    rng = np.random.default_rng(seed)
    ks = [np.arange(harmonics) * nu + j + 1 for j in range(nu)]
    amps = [1.0 / k for k in ks]
    phases = []
    for a in amps:  # Schroeder: phi_k = -pi k (k - 1) / K, a random offset per input
        k = np.arange(1, len(a) + 1)
        phases.append(-np.pi * k * (k - 1) / len(a) + rng.uniform(0, 2 * np.pi))
    grid = np.linspace(0.0, period, 4096, endpoint=False)
    peaks = np.array(
        [
            np.abs(np.sin(2 * np.pi * np.outer(grid, k) / period + ph) @ a).max()
            for k, a, ph in zip(ks, amps, phases)
        ]
    )
    gains = fraction * limits / peaks

    def u(t):
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        out = np.stack(
            [
                np.sin(2 * np.pi * np.outer(tt, k) / period + ph) @ a * g
                for k, a, ph, g in zip(ks, amps, phases, gains)
            ],
            axis=-1,
        )
        return out[0] if np.ndim(t) == 0 else out

    return u
