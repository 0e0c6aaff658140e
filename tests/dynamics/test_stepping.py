"""The fixed-step integrators' kernels: order, lanes, threads and the branch-free sin/cos."""

import numba
import numpy as np
import pytest

from dynamics import stepping
from dynamics.methods import METHODS
from dynamics.stepping import LANES_FROM
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


# the threaded integrator is compiled once for every model (dynamics.stepping): each model
# adds only its derivative, which the rest of the suite compiles too
@pytest.mark.parametrize("name", SCLERONOMIC)
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


def test_one_integrator_serves_every_model():
    """The integrator calls each model's derivative through its address (`stepping.table`),
    so it is compiled once for all models: a second model adds no overload of its own, and
    its compiled code links no model's kernel."""
    arm, x = random_states("two_link_arm", 1, seed=16)
    arm.step(x, np.zeros(arm.n_u), 0.01)
    arm.step(np.repeat(x, LANES_FROM, 0), np.zeros((LANES_FROM, arm.n_u)), 0.01)
    before = {k: list(k.signatures) for k in (stepping.erk_row, stepping.erk_rows)}
    disk, y = random_states("rolling_disk", LANES_FROM, seed=17)
    u = np.zeros((LANES_FROM, disk.n_u))
    assert np.isfinite(disk.step(y, u, 0.01)).all() and np.isfinite(disk.step(y[0], u[0])).all()
    assert {k: list(k.signatures) for k in before} == before
    linked = [v for v in stepping.erk_rows.py_func.__globals__.values() if hasattr(v, "py_func")]
    assert all(v.py_func.__module__ == "dynamics.stepping" for v in linked)


def test_a_model_s_table_holds_the_kernels_asked_for():
    arm, _ = random_states("two_link_arm", 1)
    disk, _ = random_states("rolling_disk", 1)
    t = stepping.table(arm.kernel_module, "derivative_lanes_p")
    assert t[stepping.AT_DERIVATIVE_P] != 0 and t[stepping.AT_PROJECT] == 0  # no constraints
    assert list(t[stepping.N_Q :]) == [2, 0, 2]  # n_q, n_c, K
    t = stepping.table(disk.kernel_module, "derivative_lanes")
    assert t[stepping.AT_DERIVATIVE] != 0 and t[stepping.AT_PROJECT] != 0
    assert t[stepping.AT_DERIVATIVE_W] == 0  # compiled only when asked for
    assert list(t[stepping.N_Q :]) == [5, 2, 7]  # two rolling constraints
    assert stepping.table(disk.kernel_module) is t  # one table a model, filled as asked
