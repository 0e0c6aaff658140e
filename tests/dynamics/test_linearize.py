"""`System.linearize` (exact Jacobians) against central finite differences."""

import numpy as np
import pytest

from .helpers import SCLERONOMIC, random_states


def finite_differences(system, x, u, h=1e-6):
    n2, nu = system.state_size, system.n_u
    A = np.empty((n2, n2))
    B = np.empty((n2, nu))
    for j in range(n2):
        e = np.zeros(n2)
        e[j] = h
        A[:, j] = (
            system.state_derivative(0.0, x + e, u) - system.state_derivative(0.0, x - e, u)
        ) / (2 * h)
    for j in range(nu):
        e = np.zeros(nu)
        e[j] = h
        B[:, j] = (
            system.state_derivative(0.0, x, u + e) - system.state_derivative(0.0, x, u - e)
        ) / (2 * h)
    return A, B


@pytest.mark.parametrize("name", SCLERONOMIC)
def test_linearisation_matches_finite_differences(name):
    system, xs = random_states(name, 3, seed=11)
    rng = np.random.default_rng(12)
    for x in xs:
        u = rng.normal(size=system.n_u)
        A, B = system.linearize(x, u)
        A_fd, B_fd = finite_differences(system, x, u)
        # central differences at h = 1e-6: truncation ~h^2 |f'''| ~ 1e-10, round-off
        # ~1e-16 |f| / h ~ 1e-9 for |f| up to ~10: 1e-6 leaves a wide margin
        scale = max(1.0, np.abs(A).max())
        np.testing.assert_allclose(A, A_fd, atol=1e-6 * scale)
        np.testing.assert_allclose(B, B_fd, atol=1e-6 * scale)


def test_linearisation_of_the_prescribed_rod_is_time_dependent():
    import dynamics

    rod = dynamics.get_model("bead_on_rotating_rod").compile(Omega=2.0)
    A, B = rod.linearize(np.array([0.3, 0.1]), None, t=0.4)
    np.testing.assert_allclose(A, [[0.0, 1.0], [4.0, 0.0]], rtol=1e-14)  # r'' = W^2 r - ...
    assert B.shape == (2, 0)
