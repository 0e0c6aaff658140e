"""Problem 7/2: the particle on a 4-sphere (`particle_on_4_sphere`)."""

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

import dynamics
from dynamics.integrate import simulate
from dynamics.spec import ModelSpec, Param, t

X0 = np.array([0.6, 0.2, -1.0, 0.3, 1.1, -0.7])  # theta well inside (0, pi/2), both spinning


@pytest.fixture(scope="module")
def model():
    return dynamics.get_model("particle_on_4_sphere")


@pytest.fixture(scope="module")
def system(model):
    return model.compile()


@pytest.mark.slow
def test_coordinates_cover_the_sphere_with_rank_three(model):
    theta, varphi, psi = model.spec.coordinates
    R = next(s for s in model.spec.parameters if s.name == "R")
    r = sp.Matrix([model.spec.outputs[c] for c in "wxyz"])
    assert sp.simplify((r.T * r)[0, 0] - R**2) == 0
    J = r.jacobian([theta, varphi, psi])
    generic = {theta: 0.7, varphi: 0.3, psi: -1.2, R: 1}
    assert J.subs(generic).rank() == 3
    assert J.subs(generic | {theta: 0}).rank() == 2  # psi is undefined at sin(theta) = 0


@pytest.mark.slow
def test_equations_are_lagrange_by_hand(model):
    """T = R^2 (theta'^2 + cos^2 varphi'^2 + sin^2 psi'^2) / 2, V = k R^2 cos^2 / 2."""
    theta, varphi, psi = model.spec.coordinates
    p = {s.name: s for s in model.spec.parameters}
    m, R, k = p["m"], p["R"], p["k"]
    vp, ps = varphi.diff(t), psi.diff(t)
    s, c = sp.sin(theta), sp.cos(theta)
    by_hand = sp.Matrix(
        [
            m * R**2 * (theta.diff(t, 2) + s * c * (vp**2 - ps**2)) - k * R**2 * s * c,
            (m * R**2 * c**2 * vp).diff(t),
            (m * R**2 * s**2 * ps).diff(t),
        ]
    )
    assert (model.equations() - by_hand).applyfunc(sp.simplify) == sp.zeros(3, 1)


def test_stays_on_the_sphere_and_conserves_both_cyclic_momenta_and_energy(system):
    times, states = simulate(system, X0, duration=5.0, dt=1e-3)
    out = system.outputs(times, states)
    radius = np.sqrt(sum(out[c] ** 2 for c in "wxyz"))
    np.testing.assert_allclose(radius, system.parameters["R"], rtol=1e-14)  # identity: round-off
    # RK4 at 1 ms over 5 s, rates ~1 rad/s: measured drifts ~1e-13; 1e-10 is ample
    for name in ("p_varphi", "p_psi"):
        assert np.ptp(out[name]) < 1e-10, name
    assert np.ptp(system.energy(states)) < 1e-10
    assert np.ptp(states[:, 0]) > 0.1, "theta oscillates: the test is not a trivial rotation"


def _cartesian_4d() -> ModelSpec:
    """The same particle in w, x, y, z with the sphere as a constraint (one multiplier)."""
    q = me.dynamicsymbols("w x y z")
    m, R, k = sp.symbols("m R k", positive=True)
    rates = [c.diff(t) for c in q]
    return ModelSpec(
        name="particle_4d_cartesian",
        coordinates=tuple(q),
        kinetic=m * sum(v**2 for v in rates) / 2,
        potential=k * (q[0] ** 2 + q[1] ** 2) / 2,
        constraints=(sum(c * v for c, v in zip(q, rates)),),  # d(|r|^2)/dt / 2 = 0
        parameters={m: Param(1.0, "kg"), R: Param(1.0, "m"), k: Param(2.0, "N/m")},
    )


@pytest.mark.slow  # compiles a model of its own (the Cartesian particle): ~10 s cold
def test_agrees_with_cartesian_motion_under_the_sphere_constraint(model, system):
    cart = dynamics.Model(_cartesian_4d()).compile()
    theta, varphi, psi = model.spec.coordinates
    R = next(s for s in model.spec.parameters if s.name == "R")
    r = sp.Matrix([model.spec.outputs[c] for c in "wxyz"]).subs(R, 1.0)
    J = r.jacobian([theta, varphi, psi])
    at = dict(zip((theta, varphi, psi), X0[:3]))
    r0 = np.array(r.subs(at).evalf(), dtype=float)[:, 0]
    v0 = np.array(J.subs(at).evalf(), dtype=float) @ X0[3:]
    times, states = simulate(system, X0, duration=3.0, dt=1e-3)
    _, cart_states = simulate(cart, np.concatenate([r0, v0]), duration=3.0, dt=1e-3)
    out = system.outputs(times, states)
    ours = np.stack([out[c] for c in "wxyz"], -1)
    # both RK4 at 1 ms (the Cartesian one projected on the velocity constraint each step):
    # measured agreement 4e-13 m over 3 s; a wrong term would differ by O(0.1) m
    np.testing.assert_allclose(ours, cart_states[:, :4], atol=1e-8)


def test_user_potential_must_depend_on_theta_only():
    with pytest.raises(ValueError, match="theta"):
        _ = dynamics.get_model("particle_on_4_sphere", potential="cos(varphi)").spec
