"""Which envs a test parametrised over every env steps in the fast suite.

Each env compiles kernels of its own (its integrator, its task functions and its fused
steps: 2-3 s of numba each, from a cold cache), and that compilation was most of the
default run. So such a test steps one env of each kind of model by default, and every env
with `-m slow` (CI runs both): the same checks, the whole matrix in CI.
"""

from __future__ import annotations

import pytest

FAST = (
    "Lagrange/TwoLinkArm-v1",  # holonomic, unconstrained, two inputs, drawn goals
    "Lagrange/RollingDisk-v1",  # nonholonomic constraints
    "Lagrange/BeadOnRod-v1",  # time-dependent (a prescribed rotation)
    "Lagrange/CrankSlider-v1",  # a holonomic constraint (multipliers, projection)
)


def over(ids, fast=FAST) -> list:
    """`ids` as pytest parameters: those in `fast` run by default, the rest with -m slow."""
    return [i if i in fast else pytest.param(i, marks=pytest.mark.slow) for i in ids]
