"""The rolling disk (section 7.5) against the book's eqs. (7.35)-(7.38)."""

import numpy as np
import pytest
import sympy as sp

import dynamics
from dynamics.spec import t

from .helpers import book_residuals


@pytest.fixture(scope="module")
def disk():
    return dynamics.get_model("rolling_disk")


def _names(disk):
    x, z, th, ph, ps = disk.spec.coordinates
    p = {s.name: s for s in disk.spec.parameters}
    return x, z, th, ph, ps, p


def book_737(disk, as_printed=False):
    """Eqs. (7.37) (no inputs), with lambda1, lambda2; corrected unless `as_printed`.

    Erratum: the fourth equation prints + m r zdot thetadot sin(theta) cos(phi); -dT/dphi of
    the book's own T (7.30) gives - m r zdot thetadot sin(theta) cos(phi)."""
    sign = 1 if as_printed else -1
    x, z, th, ph, ps, p = _names(disk)
    m, r, I, J, g = (p[k] for k in ("m", "r", "I", "J", "g"))
    l1, l2 = sp.symbols("lambda1 lambda2")
    xd, zd, thd, phd, psd = (c.diff(t) for c in (x, z, th, ph, ps))
    S, C = sp.sin, sp.cos
    return sp.Matrix(
        [
            (m * xd + m * r * (-thd * S(th) * C(ph) - phd * C(th) * S(ph))).diff(t) + l1,
            (m * zd + m * r * (thd * S(th) * S(ph) - phd * C(th) * C(ph))).diff(t) + l2,
            (m * r**2 * thd + m * r * (-xd * S(th) * C(ph) + zd * S(th) * S(ph)) + I * thd).diff(t)
            + m * r**2 * phd**2 * C(th) * S(th)
            + m
            * r
            * (
                xd * thd * C(th) * C(ph)
                - xd * phd * S(th) * S(ph)
                - zd * thd * C(th) * S(ph)
                - zd * phd * S(th) * C(ph)
            )
            - I * phd**2 * S(th) * C(th)
            + J * (psd + phd * C(th)) * phd * S(th)
            + m * g * r * C(th),
            (
                m * r**2 * phd * C(th) ** 2
                + m * r * (-xd * C(th) * S(ph) - zd * C(th) * C(ph))
                + I * phd * S(th) ** 2
                + J * (psd + phd * C(th)) * C(th)
            ).diff(t)
            + m
            * r
            * (
                -xd * thd * S(th) * S(ph)
                + xd * phd * C(th) * C(ph)
                + sign * zd * thd * S(th) * C(ph)
                - zd * phd * C(th) * S(ph)
            ),
            (J * (psd + phd * C(th))).diff(t) + l1 * r * S(ph) + l2 * r * C(ph),
        ]
    )


@pytest.mark.slow
def test_737_holds_at_random_rolling_states():
    """(7.37) against the compiled disk (inputs are zero in the book; here they are random,
    so the check uses (7.37) plus their generalised forces, test_drive_and_steer_...)."""
    model = dynamics.get_model("rolling_disk")
    x, z, th, ph, ps, p = _names(model)
    tau_d, tau_s = model.spec.inputs
    Q = sp.Matrix([0, 0, 0, tau_d * sp.cos(th) + tau_s, tau_d + tau_s * sp.cos(th)])
    residual = book_residuals(model, list(book_737(model) - Q))
    np.testing.assert_allclose(residual, 0.0, atol=1e-10)
    printed = book_residuals(model, list(book_737(model, as_printed=True) - Q))
    assert np.abs(printed[:, 3]).max() > 1e-3  # the printed sign is wrong (docs/errata.md)


@pytest.mark.slow  # simplifies five long expressions: ~5 s
def test_equations_equal_737_without_inputs(disk):
    ours = disk.equations().subs({u: 0 for u in disk.spec.inputs})
    diff = (ours - book_737(disk)).applyfunc(lambda e: sp.simplify(sp.expand(e)))
    assert diff == sp.zeros(5, 1)


def test_printed_737_differs_by_one_sign(disk):
    x, z, th, ph, ps, p = _names(disk)
    diff = (book_737(disk, as_printed=True) - book_737(disk)).applyfunc(sp.simplify)
    term = 2 * p["m"] * p["r"] * z.diff(t) * th.diff(t) * sp.sin(th) * sp.cos(ph)
    assert diff == sp.Matrix([0, 0, 0, term, 0])


def _book_energies(disk):
    """T from (7.30) and (7.33), V from (7.34)."""
    x, z, th, ph, ps, p = _names(disk)
    m, r, I, J, g = (p[k] for k in ("m", "r", "I", "J", "g"))
    xd, zd, thd, phd, psd = (c.diff(t) for c in (x, z, th, ph, ps))
    S, C = sp.sin, sp.cos
    v2 = (
        xd**2
        + zd**2
        + r**2 * thd**2
        + r**2 * phd**2 * C(th) ** 2
        + 2
        * r
        * (
            -xd * thd * S(th) * C(ph)
            - xd * phd * C(th) * S(ph)
            + zd * thd * S(th) * S(ph)
            - zd * phd * C(th) * C(ph)
        )
    )
    T = m * v2 / 2 + I * (thd**2 + phd**2 * S(th) ** 2) / 2 + J * (psd + phd * C(th)) ** 2 / 2
    return T, m * g * r * S(th)


@pytest.mark.slow
def test_energies_730_733_734_at_random_states():
    model = dynamics.get_model("rolling_disk")
    T, V = _book_energies(model)
    system = model.compile()
    q = model.spec.coordinates
    plain = sp.symbols("q0:5 qd0:5")
    subs = {c.diff(t): s for c, s in zip(q, plain[5:])} | dict(zip(q, plain[:5]))
    f = sp.lambdify([*plain, *model.spec.parameters], [T.subs(subs), V.subs(subs)])
    x = np.random.default_rng(5).uniform(-2.0, 2.0, (8, 10))
    book = np.array([f(*row, *system.parameters.values()) for row in x])
    np.testing.assert_allclose(system.energy_terms(x), book, rtol=1e-12, atol=1e-12)


@pytest.mark.slow  # simplifies the derived T: ~4 s
def test_energies_equal_730_733_734(disk):
    T, V = _book_energies(disk)
    assert sp.simplify(disk.derived.kinetic - T) == 0
    assert sp.simplify(disk.derived.potential - V) == 0


@pytest.mark.slow  # symbolic (4 s); the constraint residual is checked numerically elsewhere
def test_constraints_are_735_and_738(disk):
    # derived from zero velocity of the material contact point, not typed in
    x, z, th, ph, ps, p = _names(disk)
    r = p["r"]
    B = disk.derived.constraint_matrix
    expected = sp.Matrix([[1, 0, 0, 0, r * sp.sin(ph)], [0, 1, 0, 0, r * sp.cos(ph)]])
    assert (B - expected).applyfunc(sp.simplify) == sp.zeros(2, 5)
    assert disk.derived.constraint_bias == sp.zeros(2, 1)


def test_drive_and_steer_torques_enter_by_virtual_work(disk):
    x, z, th, ph, ps, p = _names(disk)
    tau_d, tau_s = disk.spec.inputs
    Q = disk.spec.forces
    assert sp.simplify(Q[th]) == 0
    assert sp.simplify(Q[ph] - (tau_d * sp.cos(th) + tau_s)) == 0
    assert sp.simplify(Q[ps] - (tau_d + tau_s * sp.cos(th))) == 0


def test_upright_straight_rolling_is_a_steady_motion():
    system = dynamics.get_model("rolling_disk").compile()
    r = system.parameters["r"]
    psidot = -5.0
    x = np.array(
        [
            0.0,
            0.0,
            np.pi / 2,
            0.3,
            0.0,
            -r * psidot * np.sin(0.3),
            -r * psidot * np.cos(0.3),
            0.0,
            0.0,
            psidot,
        ]
    )
    np.testing.assert_allclose(system.constraint_residual(x), 0.0, atol=1e-15)
    # upright, straight: all accelerations vanish (to round-off of O(1) terms)
    np.testing.assert_allclose(system.accelerations(0.0, x), 0.0, atol=1e-13)


def test_contact_point_moves_in_the_floor_plane_xz():
    """Section 7.5 says the contact point moves "in the (x, y) plane"; the floor is y = 0, so
    it moves in the (x, z) plane, along i' = sin(phi) i + cos(phi) k (docs/errata.md)."""
    system = dynamics.get_model("rolling_disk").compile()
    assert system.coordinates[:2] == ("x", "z")  # no y: the contact stays on the floor
    rng = np.random.default_rng(3)
    x = np.zeros((20, 10))
    x[:, 2:5] = rng.uniform(0.3, 2.8, (20, 3))
    x[:, 5:] = rng.uniform(-2.0, 2.0, (20, 5))
    x = system.project(x)
    phi, psid, r = x[:, 3], x[:, 9], system.parameters["r"]
    np.testing.assert_allclose(x[:, 5], -r * psid * np.sin(phi), atol=1e-12)
    np.testing.assert_allclose(x[:, 6], -r * psid * np.cos(phi), atol=1e-12)


def test_disk_leans_towards_j_cross_i_prime():
    """The centre sits r cos(theta) from the contact along j x i' (Fig. 7-8's x-bar, z-bar,
    whose T the model reproduces in test_energies_equal_730_733_734): the lean direction of
    rolling_disk's docstring."""
    th, ph, r = sp.symbols("theta phi r")
    i_prime = sp.Matrix([sp.sin(ph), 0, sp.cos(ph)])  # (i, j, k) components
    j = sp.Matrix([0, 1, 0])
    centre_offset = sp.Matrix(
        [r * sp.cos(th) * sp.cos(ph), r * sp.sin(th), -r * sp.cos(th) * sp.sin(ph)]
    )
    horizontal = sp.Matrix([centre_offset[0], 0, centre_offset[2]])
    assert sp.simplify(horizontal - r * sp.cos(th) * j.cross(i_prime)) == sp.zeros(3, 1)
