"""Integration: energy conservation, convergence order, agreement with DOP853, input power."""

import numpy as np
import pytest

from dynamics.integrate import DEFAULT_DT, reference, simulate

from .helpers import SCLERONOMIC, random_states


def _relative_drift(system, x0, xs):
    E0 = system.energy(x0)
    return np.max(np.abs(system.energy(xs) - E0) / np.abs(E0))


@pytest.mark.parametrize("name", SCLERONOMIC)
def test_unforced_motion_conserves_energy(name):
    system, x0 = random_states(name, 16)
    _, xs = simulate(system, x0, duration=10.0)
    # the promise of the default step (DEFAULT_DT): relative drift <= 1e-6 over 10 s
    assert _relative_drift(system, x0, xs) <= 1e-6


@pytest.mark.parametrize("name", ["two_link_arm", "rolling_disk"])
def test_energy_error_falls_at_fourth_order(name):
    system, x0 = random_states(name, 8, seed=1)
    drifts = []
    for dt in (4e-3, 2e-3):
        _, xs = simulate(system, x0, duration=5.0, dt=dt)
        drifts.append(_relative_drift(system, x0, xs))
    # RK4's global error is O(h^4): halving h divides it by ~16; 10..22 allows for the
    # error constant changing a little with h over chaotic 5 s arcs
    assert 10.0 < drifts[0] / drifts[1] < 22.0


@pytest.mark.parametrize("name", SCLERONOMIC)
def test_rk4_agrees_with_dop853(name):
    system, x0 = random_states(name, 3, seed=2)
    times = np.linspace(0.0, 2.0, 5)
    for x in x0:
        ref = reference(system, x, times)
        _, xs = simulate(system, x, duration=2.0, dt=DEFAULT_DT)
        # RK4 at 1e-3 is accurate to ~1e-9 per unit time on these motions (error ~ h^4 times
        # O(10) derivatives); 2 s of chaotic motion amplifies differences ~100x: 1e-6
        np.testing.assert_allclose(xs[::500], ref, atol=1e-6)


def test_disk_constraints_stay_at_round_off():
    system, x0 = random_states("rolling_disk", 8, seed=3)
    _, xs = simulate(system, x0, duration=10.0)
    # projection after each step: residuals are products of O(1..10) numbers, ~1e-14
    assert np.abs(system.constraint_residual(xs)).max() < 1e-12


@pytest.mark.parametrize("name", SCLERONOMIC)
def test_energy_rate_equals_input_power(name):
    system, x = random_states(name, 8, seed=4)
    rng = np.random.default_rng(5)
    u = rng.uniform(-2.0, 2.0, (8, system.n_u))
    f = system.state_derivative(0.0, x, u)
    h = 1e-6
    dE = (system.energy(x + h * f) - system.energy(x - h * f)) / (2 * h)
    # central difference: truncation O(h^2) ~ 1e-12, round-off ~ 1e-16 * E / h ~ 1e-9
    np.testing.assert_allclose(dE, system.power(0.0, x, u), rtol=1e-6, atol=1e-7)


def test_batched_calls_equal_single_calls():
    for name in SCLERONOMIC:
        system, x = random_states(name, 6, seed=6)
        u = np.random.default_rng(7).normal(size=(6, system.n_u))
        batched = system.state_derivative(0.0, x, u)
        single = np.array([system.state_derivative(0.0, xi, ui) for xi, ui in zip(x, u)])
        np.testing.assert_array_equal(batched, single)  # the same kernel row by row: exact
        np.testing.assert_array_equal(system.energy(x), [system.energy(xi) for xi in x])
        stepped = system.step(x, u, 0.05, 5)
        np.testing.assert_array_equal(
            stepped, [system.step(xi, ui, 0.05, 5) for xi, ui in zip(x, u)]
        )


def test_leading_batch_shapes_broadcast():
    system, x = random_states("two_link_arm", 6)
    xb = x.reshape(2, 3, 4)
    assert system.state_derivative(0.0, xb, np.zeros(2)).shape == (2, 3, 4)
    assert system.energy(xb).shape == (2, 3)
    assert system.step(xb, np.zeros((2, 3, 2)), 0.01).shape == (2, 3, 4)


@pytest.mark.parametrize("name", SCLERONOMIC)
def test_column_wise_large_batches_agree_with_the_kernel(name):
    from dynamics.system import VECTORIZE_FROM

    system, x = random_states(name, VECTORIZE_FROM + 3, seed=8)
    u = np.random.default_rng(9).normal(size=(len(x), system.n_u))
    large = system.state_derivative(0.0, x, u)
    rows = np.concatenate(
        [system.state_derivative(0.0, x[i : i + 1], u[i : i + 1]) for i in range(len(x))]
    )
    # two orders of floating-point operations (no pivoting vs pivoting): round-off only
    np.testing.assert_allclose(large, rows, rtol=1e-10, atol=1e-10)
