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


@pytest.mark.parametrize("name", ["two_link_arm", "rolling_disk"])
def test_interpreted_linearisation_equals_the_compiled_kernels(name, monkeypatch):
    """A model's first linearisations run its generated code as Python (no compilation);
    later ones the compiled kernel: the same arithmetic in the same order."""
    from dynamics import interpreted as interp

    system, xs = random_states(name, 3, seed=21)
    rng = np.random.default_rng(22)
    us = rng.normal(size=(3, system.n_u))
    monkeypatch.setattr(interp, "_interpreted_points", {})
    monkeypatch.setattr(interp, "_compiled", lambda m: False)  # whatever ran before
    programs = []
    for name_py in ("linear_terms_py", "kkt_py"):
        program = getattr(interp, name_py)
        counted = lambda *a, f=program: programs.append(f) or f(*a)  # noqa: E731
        monkeypatch.setattr(interp, name_py, counted)
    interpreted = [system.linearize(x, u) for x, u in zip(xs, us)]
    kkts = [system.kkt(x, u) for x, u in zip(xs, us)]
    assert len(programs) == 6  # every one of them ran as Python
    monkeypatch.setattr(interp, "INTERPRETED_POINTS", 0)
    for x, u, (A, B), (K, r) in zip(xs, us, interpreted, kkts):
        A_c, B_c = system.linearize(x, u)
        # Python's floats and numba's are both IEEE doubles with the same operations in the
        # same order and the same libm: equal up to a last-bit difference in a power
        scale = max(1.0, np.abs(A_c).max())
        np.testing.assert_allclose(A, A_c, rtol=0, atol=1e-14 * scale)
        np.testing.assert_allclose(B, B_c, rtol=0, atol=1e-14 * scale)
        K_c, r_c = system.kkt(x, u)
        np.testing.assert_allclose(K, K_c, rtol=0, atol=1e-14 * max(1.0, np.abs(K_c).max()))
        np.testing.assert_allclose(r, r_c, rtol=0, atol=1e-14 * max(1.0, np.abs(r_c).max()))
    assert system.kernel_module.linear_terms.signatures


def test_interpreted_linearisation_falls_back_where_python_raises(monkeypatch):
    """A division by zero raises in Python and gives inf in the kernels: the compiled
    kernel then runs, and the error is the one the checks give for a non-finite result."""
    from dynamics import interpreted as interp

    system, xs = random_states("two_link_arm", 1, seed=23)
    monkeypatch.setattr(interp, "_interpreted_points", {})
    monkeypatch.setattr(interp, "_compiled", lambda m: False)

    def divide_by_zero(*args):
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setattr(interp, "linear_terms_py", divide_by_zero)
    A, B = system.linearize(xs[0], np.zeros(system.n_u))
    assert system.kernel_module.linear_terms.signatures
    assert np.isfinite(A).all() and np.isfinite(B).all()


@pytest.mark.parametrize("name", ["two_link_arm", "rolling_disk"])
def test_interpreted_accelerations_equal_the_compiled_kernel(name, monkeypatch):
    """The few accelerations an env's checks ask for when it is made run the generated code
    as Python (no compilation of a kernel the first step does not use); a larger batch, or
    any once the budget is spent, the compiled kernel: the same numbers up to the last bit
    of a power (Python's libm `pow`, numba's products)."""
    from dynamics import interpreted as interp

    system, xs = random_states(name, 5, seed=31)
    us = np.random.default_rng(32).normal(size=(5, system.n_u))
    monkeypatch.setattr(interp, "_interpreted_points", {})
    monkeypatch.setattr(interp.cache, "compiled", lambda kernel: False)
    program = interp.accelerations_py
    ran = []
    counted = lambda *a: ran.append(1) or program(*a)  # noqa: E731
    monkeypatch.setattr(interp, "accelerations_py", counted)
    qdd, lam = system.accelerations(0.0, xs, us), system.multipliers(0.0, xs, us)
    assert len(ran) == 10  # every row of both calls ran as Python
    many = np.repeat(xs, interp.INTERPRETED_ROWS // 5 + 1, axis=0)
    system.accelerations(0.0, many, np.zeros((len(many), system.n_u)))
    assert len(ran) == 10  # a large batch goes to the kernel
    monkeypatch.setattr(interp, "INTERPRETED_POINTS", 0)
    qdd_c, lam_c = system.accelerations(0.0, xs, us), system.multipliers(0.0, xs, us)
    assert len(ran) == 10
    scale = max(1.0, np.abs(qdd_c).max(), np.abs(lam_c).max() if lam_c.size else 0.0)
    np.testing.assert_allclose(qdd, qdd_c, rtol=0, atol=1e-14 * scale)
    np.testing.assert_allclose(lam, lam_c, rtol=0, atol=1e-14 * scale)
