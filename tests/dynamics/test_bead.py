"""Problem 7/4: the bead on a rod spun at constant rate, and the driven rod."""

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import cumulative_simpson

import dynamics
from dynamics.integrate import simulate
from dynamics.spec import t


@pytest.fixture(scope="module")
def rod():
    return dynamics.get_model("bead_on_rotating_rod").compile(Omega=2.0)


def closed_form(t, r0, v0, Omega, g):
    """r'' = Omega^2 r - g sin(Omega t): r = A cosh + B sinh + g/(2 Omega^2) sin(Omega t)."""
    c = g / (2 * Omega**2)
    B = (v0 - c * Omega) / Omega
    return r0 * np.cosh(Omega * t) + B * np.sinh(Omega * t) + c * np.sin(Omega * t)


def test_equation_is_the_linear_one():
    model = dynamics.get_model("bead_on_rotating_rod")
    (r,) = model.spec.coordinates
    p = {s.name: s for s in model.spec.parameters}
    m, g, W = p["m"], p["g"], p["Omega"]
    expected = m * (r.diff(t, 2) - W**2 * r + g * sp.sin(W * t))
    assert sp.simplify(model.equations()[0] - expected) == 0


def test_follows_the_closed_form_over_several_periods(rod):
    W, g = rod.parameters["Omega"], rod.parameters["g"]
    # start on the bounded branch (B = -A ... chosen so cosh/sinh growth cancels: r0 = 0,
    # v0 = g/(2 Omega)) so that the motion stays O(1) over three rod periods
    x0 = np.array([0.0, g / (2 * W)])
    duration = 3 * 2 * np.pi / W
    times, xs = simulate(rod, x0, duration=round(duration, 3), dt=1e-3)
    exact = closed_form(times, 0.0, g / (2 * W), W, g)
    # RK4 at 1e-3 on a smooth O(1) solution: error ~1e-11; the unstable cosh mode
    # amplifies it by e^(W t) ~ e^19 over three periods, hence 1e-4 relative to g/(2W^2)
    np.testing.assert_allclose(xs[:, 0], exact, atol=1e-4 * g / (2 * W**2))


def test_follows_the_closed_form_from_rest_off_centre(rod):
    W, g = rod.parameters["Omega"], rod.parameters["g"]
    times, xs = simulate(rod, np.array([0.1, 0.0]), duration=2.0, dt=1e-3)
    exact = closed_form(times, 0.1, 0.0, W, g)
    np.testing.assert_allclose(xs[:, 0], exact, rtol=1e-9, atol=1e-10)  # RK4 ~1e-12 per step


def test_energy_gained_equals_work_of_the_driving_torque(rod):
    W = rod.parameters["Omega"]
    times, xs = simulate(rod, np.array([0.2, 0.1]), duration=2.0, dt=1e-3)
    E = rod.energy(xs, t=times)
    torque = rod.outputs(times, xs)["reaction_phi"]
    power = rod.power(times, xs)
    np.testing.assert_allclose(power, torque * W, rtol=1e-12, atol=1e-12)
    # Simpson quadrature of a smooth power at dt = 1e-3: error ~ dt^4 * P'''' * T ~ 1e-12 E
    work = cumulative_simpson(power, x=times, initial=0.0)
    np.testing.assert_allclose(E - E[0], work, rtol=1e-9, atol=1e-9 * np.abs(E).max())


def test_driving_torque_formula(rod):
    # torque = d/dt(m r^2 W) + m g r cos(W t) = 2 m r rdot W + m g r cos(W t)
    m, g, W = (rod.parameters[k] for k in ("m", "g", "Omega"))
    x, time = np.array([0.3, -0.4]), 0.7
    torque = rod.outputs(time, x)["reaction_phi"]
    assert torque == pytest.approx(
        2 * m * 0.3 * -0.4 * W + m * g * 0.3 * np.cos(W * time), rel=1e-14
    )


def test_driven_rod_reduces_to_the_prescribed_rod_at_constant_rate():
    driven = dynamics.get_model("bead_on_driven_rod").compile()
    rod = dynamics.get_model("bead_on_rotating_rod").compile(Omega=1.5, m=driven.parameters["m"])
    time, r, rdot = 0.4, 0.3, -0.2
    phi = 1.5 * time
    x = np.array([r, phi, rdot, 1.5])
    # the torque that keeps phidot constant is the prescribed rod's reaction
    tau = rod.outputs(time, [r, rdot])["reaction_phi"]
    acc = driven.accelerations(0.0, x, [tau])
    assert acc[1] == pytest.approx(0.0, abs=1e-12)
    assert acc[0] == pytest.approx(rod.accelerations(time, [r, rdot])[0], rel=1e-12)


def test_power_counts_given_forces_on_a_prescribed_coordinate():
    """A given torque on the spun rod changes the drive's reaction, not the energy balance:
    d(T + V)/dt = (reaction + given torque) * Omega."""
    import sympy.physics.mechanics as me

    from dynamics.models.bead import _bead_energies
    from dynamics.spec import ModelSpec, Param

    r, phi = me.dynamicsymbols("r phi")
    m, g, W = sp.symbols("m g Omega", positive=True)
    c = sp.Symbol("c")
    T, V = _bead_energies(r, phi, m, g)
    spec = ModelSpec(
        name="bead_with_rod_torque",
        coordinates=(r,),
        kinetic=T,
        potential=V,
        prescribed={phi: W * t},
        forces={phi: c},
        parameters={
            m: Param(0.1, "kg"),
            g: Param(9.81, "m/s^2"),
            W: Param(2.0, "rad/s"),
            c: Param(0.7, "N*m", positive=False),
        },
    )
    system = dynamics.Model(spec).compile()
    x, time = np.array([0.3, -0.2]), 0.4
    f = system.state_derivative(time, x)
    h = 1e-6
    dE = (system.energy(x + h * f, t=time + h) - system.energy(x - h * f, t=time - h)) / (2 * h)
    reaction = system.outputs(time, x)["reaction_phi"]
    # central difference: O(h^2) truncation and ~1e-16 E / h round-off, both below 1e-8
    assert system.power(time, x) == pytest.approx(dE, abs=1e-8)
    assert system.power(time, x) == pytest.approx((reaction + 0.7) * 2.0, rel=1e-12)
