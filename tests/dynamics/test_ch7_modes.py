"""Modal analysis of the arm's small-angle equations (7.26): one rapid mode, one slow."""

import numpy as np
import pytest

import dynamics
from dynamics.integrate import simulate
from dynamics.modes import mass_and_stiffness, modes, small_oscillations


@pytest.fixture(scope="module")
def arm():
    return dynamics.get_model("two_link_arm")


@pytest.mark.slow
def test_matrices_are_those_of_726(arm):
    p = arm.parameters
    M, K = mass_and_stiffness(arm, [0.0, 0.0])
    I_prime = p["Ibar1"] + p["m1"] * p["l1"] ** 2 + p["m2"] * p["l"] ** 2
    I2 = p["Ibar2"] + p["m2"] * p["l2"] ** 2
    A = p["m2"] * p["l"] * p["l2"]
    B = (p["m1"] * p["l1"] + p["m2"] * p["l"]) * p["g"]
    C = p["m2"] * p["g"] * p["l2"]
    # exact rationals and g evaluated in double precision
    np.testing.assert_allclose(M, [[I_prime, A], [A, I2]], rtol=1e-14)
    np.testing.assert_allclose(K, [[B, 0.0], [0.0, C]], rtol=1e-14, atol=1e-14)


def test_frequencies_of_two_uniform_rods_are_the_closed_form(arm):
    """For two uniform rods of length l: omega^2 = (g / l) (3 -+ 6 / sqrt 7)."""
    result = small_oscillations(arm, [0.0, 0.0])
    g, l = arm.parameters["g"], arm.parameters["l"]
    closed = np.sqrt(g / l * (3 + np.array([-1.0, 1.0]) * 6 / np.sqrt(7)))
    np.testing.assert_allclose(result.frequencies, closed, rtol=1e-12)  # both double precision
    assert result.frequencies[1] / result.frequencies[0] > 2.5  # one rapid, one slow
    M, K = mass_and_stiffness(arm, [0.0, 0.0])
    # and independently of the symmetric solver: eigenvalues of M^-1 K
    independent = np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real))
    np.testing.assert_allclose(result.frequencies, independent, rtol=1e-12)
    shapes = result.shapes
    np.testing.assert_allclose(shapes.T @ M @ shapes, np.eye(2), atol=1e-12)
    assert shapes[0, 0] * shapes[1, 0] > 0 and shapes[0, 1] * shapes[1, 1] < 0  # in/anti-phase


def _zero_crossing_period(times, signal):
    """Mean period from successive upward zero crossings (linear interpolation)."""
    k = np.flatnonzero((signal[:-1] < 0) & (signal[1:] >= 0))
    crossings = times[k] - signal[k] * (times[k + 1] - times[k]) / (signal[k + 1] - signal[k])
    return np.diff(crossings).mean()


@pytest.mark.parametrize("mode", [0, 1])
def test_long_small_amplitude_nonlinear_motion_oscillates_at_the_modal_period(arm, mode):
    result = small_oscillations(arm, [0.0, 0.0])
    system = arm.compile()
    shape = result.shapes[:, mode] / np.abs(result.shapes[:, mode]).max()
    amplitude = 1e-3  # rad: the nonlinear period shift is O(amplitude^2) ~ 1e-6 relative
    x0 = np.concatenate([amplitude * shape, [0.0, 0.0]])
    period = result.periods[mode]
    steps_per_period = 400
    dt = period / steps_per_period
    times, states = simulate(system, x0, duration=20 * period, dt=dt)
    measured = _zero_crossing_period(times, states[:, 0])
    # measured 4e-8 (slow mode) and 9e-7 (rapid mode, its velocity terms larger): the
    # amplitude shift dominates; crossing interpolation (sine nearly straight at its zero)
    # and RK4 phase error, ~(omega dt)^4 ~ 6e-8, are smaller. A wrong frequency is off by %.
    np.testing.assert_allclose(measured, period, rtol=5e-6)
    # started in one mode the arm stays in it: the other coordinate keeps the shape's ratio
    ratio = states[:, 1] / states[:, 0]
    big = np.abs(states[:, 0]) > 0.5 * amplitude * abs(shape[0])
    # measured within 2e-6 of the ratio (the same O(amplitude^2) nonlinearity)
    np.testing.assert_allclose(ratio[big], shape[1] / shape[0], rtol=1e-4)


def test_bad_matrices_are_refused_by_name():
    with pytest.raises(ValueError, match="mass must be a square"):
        modes(np.ones((2, 3)), np.eye(2))
    with pytest.raises(ValueError, match="stiffness must be symmetric"):
        modes(np.eye(2), [[1.0, 2.0], [0.0, 1.0]])
    with pytest.raises(ValueError, match="positive definite"):
        modes([[1.0, 0.0], [0.0, -1.0]], np.eye(2))
    with pytest.raises(ValueError, match="unstable"):
        modes(np.eye(2), [[1.0, 0.0], [0.0, -1.0]])


def test_non_equilibrium_is_refused(arm):
    with pytest.raises(ValueError, match="not an equilibrium"):
        mass_and_stiffness(arm, [0.3, 0.0])
    with pytest.raises(ValueError, match="Unknown parameter"):
        mass_and_stiffness(arm, [0.0, 0.0], mass=2.0)
