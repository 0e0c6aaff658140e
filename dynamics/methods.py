"""Fixed-step explicit Runge-Kutta methods for `System.step`: their Butcher tableaus.

`rk4` is the classical fourth-order method (4 derivative evaluations per step). `dop853` is
the eighth-order solution of Dormand and Prince's DOP853 pair (Hairer, Norsett and Wanner,
Solving Ordinary Differential Equations I, section II.10; the coefficients as in scipy's
`dop853_coefficients`, rounded to double), taken at a fixed step without its error
estimate: 12 evaluations per step, and at the step sizes the environments use its error
per evaluation is orders of magnitude below RK4's (benchmarks/env_speed.py,
tests/envs/test_physics.py).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Tableau(NamedTuple):
    """a (s, s) strictly lower triangular, b (s,) weights, c (s,) nodes; `order` of the
    method's global error."""

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    order: int

    @property
    def stages(self) -> int:
        """Derivative evaluations per step."""
        return len(self.b)


def _tableau(rows, b, c, order: int) -> Tableau:
    s = len(b)
    a = np.zeros((s, s))
    for i, row in enumerate(rows):
        a[i, : len(row)] = row
    return Tableau(a, np.array(b, dtype=np.float64), np.array(c, dtype=np.float64), order)


DOP853_A = (
    (),
    (0.05260015195876773,),
    (0.0197250569845379, 0.0591751709536137),
    (0.02958758547680685, 0.0, 0.08876275643042054),
    (0.2413651341592667, 0.0, -0.8845494793282861, 0.924834003261792),
    (0.037037037037037035, 0.0, 0.0, 0.17082860872947386, 0.12546768756682242),
    (0.037109375, 0.0, 0.0, 0.17025221101954405, 0.06021653898045596, -0.017578125),
    (
        0.03709200011850479,
        0.0,
        0.0,
        0.17038392571223998,
        0.10726203044637328,
        -0.015319437748624402,
        0.008273789163814023,
    ),
    (
        0.6241109587160757,
        0.0,
        0.0,
        -3.3608926294469414,
        -0.868219346841726,
        27.59209969944671,
        20.154067550477894,
        -43.48988418106996,
    ),
    (
        0.47766253643826434,
        0.0,
        0.0,
        -2.4881146199716677,
        -0.590290826836843,
        21.230051448181193,
        15.279233632882423,
        -33.28821096898486,
        -0.020331201708508627,
    ),
    (
        -0.9371424300859873,
        0.0,
        0.0,
        5.186372428844064,
        1.0914373489967295,
        -8.149787010746927,
        -18.52006565999696,
        22.739487099350505,
        2.4936055526796523,
        -3.0467644718982196,
    ),
    (
        2.273310147516538,
        0.0,
        0.0,
        -10.53449546673725,
        -2.0008720582248625,
        -17.9589318631188,
        27.94888452941996,
        -2.8589982771350235,
        -8.87285693353063,
        12.360567175794303,
        0.6433927460157636,
    ),
)
DOP853_B = (
    0.054293734116568765,
    0.0,
    0.0,
    0.0,
    0.0,
    4.450312892752409,
    1.8915178993145003,
    -5.801203960010585,
    0.3111643669578199,
    -0.1521609496625161,
    0.20136540080403034,
    0.04471061572777259,
)
DOP853_C = (
    0.0,
    0.05260015195876773,
    0.0789002279381516,
    0.1183503419072274,
    0.2816496580927726,
    0.3333333333333333,
    0.25,
    0.3076923076923077,
    0.6512820512820513,
    0.6,
    0.8571428571428571,
    1.0,
)

METHODS: dict[str, Tableau] = {
    "rk4": _tableau(
        ((), (0.5,), (0.0, 0.5), (0.0, 0.0, 1.0)),
        (1 / 6, 1 / 3, 1 / 3, 1 / 6),
        (0.0, 0.5, 0.5, 1.0),
        4,
    ),
    "dop853": _tableau(DOP853_A, DOP853_B, DOP853_C, 8),
}
"""The integrators `System.step` and the environments offer, by name."""
