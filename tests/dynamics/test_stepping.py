"""The fixed-step integrators' kernels: order, lanes, threads and the branch-free sin/cos."""

import numba
import numpy as np
import pytest

from dynamics.methods import METHODS
from dynamics.system import BLOCK

from .helpers import SCLERONOMIC, random_states


@pytest.mark.parametrize("method", list(METHODS))
def test_global_error_falls_at_the_methods_order(method):
    system, x0 = random_states("two_link_arm", 4, seed=11)
    u = np.zeros((4, 2))
    ref = system.step(x0, u, 0.5, 400, method="dop853")
    order = METHODS[method].order
    steps = (100, 200) if order == 4 else (16, 32)  # where the error is asymptotic
    errors = [np.abs(system.step(x0, u, 0.5, n, method=method) - ref).max() for n in steps]
    # halving the step divides the error by 2^order (a little more or less off asymptotics)
    assert 2 ** (order - 1) < errors[0] / errors[1] < 2 ** (order + 1)


# the arm's threaded kernels by default; the disk's and the driven bead's only with -m slow:
# they are compiled for this test alone (about 4-5 s of CPU each from a cold cache)
@pytest.mark.parametrize(
    "name",
    [n if n == "two_link_arm" else pytest.param(n, marks=pytest.mark.slow)
     for n in SCLERONOMIC],
)  # fmt: skip
@pytest.mark.parametrize("method", list(METHODS))
def test_rows_step_alike_whatever_shares_their_block_and_however_many_threads(name, method):
    n = 3 * BLOCK + 5  # several blocks and a ragged last one
    system, x = random_states(name, n, seed=12)
    u = np.random.default_rng(13).normal(size=(n, system.n_u))
    T = np.zeros(n)
    one = np.empty_like(x)
    system.step_unchecked(T, x, u, 0.05, 2, one, method, 1)
    for threads in (2, numba.config.NUMBA_NUM_THREADS):
        many = np.empty_like(x)
        system.step_unchecked(T, x, u, 0.05, 2, many, method, threads)
        np.testing.assert_array_equal(many, one)
    rows = [system.step(x[i], u[i], 0.05, 2, method=method) for i in (0, 70, n - 1)]
    np.testing.assert_array_equal(np.array(rows), one[[0, 70, n - 1]])


def test_unknown_integrator_is_named():
    system, x = random_states("two_link_arm", 1)
    msg = r"Unknown integrator 'rk5'. Did you mean 'rk4'\? Known: rk4, dop853"
    with pytest.raises(ValueError, match=msg):
        system.step(x, None, 0.01, method="rk5")


def test_lane_sin_and_cos_match_libm():
    system, _ = random_states("two_link_arm", 1)
    m = system._m
    rng = np.random.default_rng(14)
    x = np.r_[
        rng.uniform(-1e5, 1e5, 20000), rng.uniform(-4, 4, 20000), np.arange(-64, 65) * np.pi / 2
    ]

    @numba.njit
    def both(x, s, c):
        for i in range(x.shape[0]):
            s[i], c[i] = m.vsin(x[i]), m.vcos(x[i])

    s, c = np.empty_like(x), np.empty_like(x)
    both(x, s, c)
    # within 2 ulp of the result, or of 1 where the result is tiny (|x| near k pi/2)
    np.testing.assert_array_less(
        np.abs(s - np.sin(x)), 2 * np.spacing(np.maximum(np.abs(np.sin(x)), 1))
    )
    np.testing.assert_array_less(
        np.abs(c - np.cos(x)), 2 * np.spacing(np.maximum(np.abs(np.cos(x)), 1))
    )
    bad = np.array([np.nan, np.inf, -np.inf])
    s, c = np.empty(3), np.empty(3)
    both(bad, s, c)
    assert np.isnan(s).all() and np.isnan(c).all()


@pytest.mark.parametrize("method", list(METHODS))
def test_a_few_rows_step_as_they_do_among_many(method):
    """`System.step` takes fewer rows than the vector lanes one at a time (`erk_row`,
    without compiling the lanes' kernels): bit for bit the rows of a large batch."""
    system, x = random_states("two_link_arm", 2 * BLOCK, seed=14)
    u = np.random.default_rng(15).normal(size=(len(x), system.n_u))
    many = system.step(x, u, 0.05, 3, method=method)
    for rows in (slice(0, 1), slice(5, 8), slice(9, 16)):
        assert np.array_equal(system.step(x[rows], u[rows], 0.05, 3, method=method), many[rows])
