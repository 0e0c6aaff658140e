"""Angle wrapping, the one definition every layer uses."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def wrap(a):
    """Angles wrapped to [-pi, pi) (scalars or arrays; callable from numba code too)."""
    return (a + np.pi) % (2 * np.pi) - np.pi
