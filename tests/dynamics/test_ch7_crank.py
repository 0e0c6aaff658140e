"""Problem 7/3: the eccentric disk and slider (`eccentric_disk_slider`)."""

import numpy as np
import pytest

import dynamics
from dynamics.integrate import reference, simulate

OFFSET = {"h": 0.05, "s": -0.03}  # slider line below O and G opposite P: no symmetry helps


@pytest.fixture(scope="module")
def crank():
    return dynamics.get_model("eccentric_disk_slider").compile()


def test_model_declares_the_contract(crank):
    assert crank.coordinates == ("theta",)
    assert crank.inputs == ("tau",)
    assert {"slider_x", "slider_v", "rod_tension", "normal_force"} <= set(crank.output_names)


@pytest.mark.parametrize("params", [{}, OFFSET])
def test_slider_sits_on_its_line_one_rod_length_from_the_pin(crank, params):
    sys = crank.with_parameters(**params)
    p = sys.parameters
    theta = np.linspace(-np.pi, np.pi, 37)
    x = np.stack([theta, np.zeros_like(theta)], axis=-1)
    slider = sys.outputs(0.0, x, np.zeros((theta.size, 1)))["slider_x"]
    pin_x, pin_y = p["R"] * np.cos(theta), p["R"] * np.sin(theta)
    rod = np.hypot(slider - pin_x, pin_y + p["h"])
    # closed-form sqrt of O(0.1 m) numbers: round-off only
    np.testing.assert_allclose(rod, p["l"], rtol=1e-13)
    assert np.all(slider > pin_x), "the slider stays on the branch to the right of the pin"


def test_slider_velocity_is_the_rate_of_its_position(crank):
    sys = crank.with_parameters(**OFFSET)
    theta, rate, d = np.linspace(-3.0, 3.0, 13), 1.7, 1e-6
    u = np.zeros((theta.size, 1))

    def slider(th):
        return sys.outputs(0.0, np.stack([th, np.zeros_like(th)], -1), u)["slider_x"]

    v = sys.outputs(0.0, np.stack([theta, np.full_like(theta, rate)], -1), u)["slider_v"]
    fd = (slider(theta + d) - slider(theta - d)) / (2 * d) * rate
    # central difference: truncation ~ d^2 x''' ~ 1e-13, round-off ~ 1e-16 / d ~ 1e-10
    np.testing.assert_allclose(v, fd, atol=1e-8)


def test_dead_centres_are_where_rod_and_crank_line_up(crank):
    """With h = 0 the slider is at its extremes l +- R, and momentarily still, at theta = 0
    and pi: there a force on the slider exerts no torque on the disk."""
    p = crank.parameters
    x = np.array([[0.0, 3.0], [np.pi, 3.0]])
    out = crank.outputs(0.0, x, np.zeros((2, 1)))
    # closed forms evaluated in double precision
    np.testing.assert_allclose(out["slider_x"], [p["l"] + p["R"], p["l"] - p["R"]], rtol=1e-14)
    np.testing.assert_allclose(out["slider_v"], 0.0, atol=1e-15)


def test_lagrange_agrees_with_newton_euler_for_the_disk(crank):
    """I theta'' = tau - M g s cos(theta) + moment about O of the rod's pull at P, with the
    rod tension that the slider's own Newton equation needs (output `rod_tension`)."""
    sys = crank.with_parameters(**OFFSET)
    p = sys.parameters
    rng = np.random.default_rng(0)
    x = np.stack([rng.uniform(-np.pi, np.pi, 20), rng.uniform(-8, 8, 20)], -1)
    u = rng.uniform(-1, 1, (20, 1))
    acc = sys.accelerations(0.0, x, u)[:, 0]
    out = sys.outputs(0.0, x, u)
    th = x[:, 0]
    pin = np.stack([p["R"] * np.cos(th), p["R"] * np.sin(th)], -1)
    slider = np.stack([out["slider_x"], np.full_like(th, -p["h"])], -1)
    pull = out["rod_tension"][:, None] * (slider - pin) / p["l"]  # rod on the disk, at P
    moment = pin[:, 0] * pull[:, 1] - pin[:, 1] * pull[:, 0]
    rhs = u[:, 0] - p["M"] * p["g"] * p["s"] * np.cos(th) + moment
    # both sides O(10) N*m from the same double-precision state: round-off
    np.testing.assert_allclose(p["I"] * acc, rhs, rtol=1e-10, atol=1e-12)


def test_slider_at_rest_presses_with_its_weight(crank):
    p = crank.parameters
    theta = 0.4
    hold = p["M"] * p["g"] * p["s"] * np.cos(theta)  # motor torque that balances gravity on G
    x = np.array([theta, 0.0])
    np.testing.assert_allclose(crank.accelerations(0.0, x, [hold]), 0.0, atol=1e-12)
    out = crank.outputs(0.0, x, [hold])
    np.testing.assert_allclose(out["rod_tension"], 0.0, atol=1e-12)
    np.testing.assert_allclose(out["normal_force"], p["m"] * p["g"], rtol=1e-14)


def test_free_mechanism_conserves_energy_and_matches_the_reference(crank):
    sys = crank.with_parameters(**OFFSET)
    x0 = np.array([0.2, 12.0])  # enough to carry the disk over the top again and again
    times, states = simulate(sys, x0, duration=3.0, dt=0.002)
    energy = sys.energy(states)
    # RK4 at h = 2 ms with theta' ~ 12 rad/s: (theta' h)^4 ~ 3e-7 bounds the relative drift
    # per unit time; measured 2e-9 over the 3 s, so 1e-7 leaves room and still catches an
    # equation that does not conserve energy (a wrong term drifts by percent)
    assert np.ptp(energy) < 1e-7 * abs(energy[0])
    ref = reference(sys, x0, times[::100])
    # global RK4 error measured 5e-8 rad (DOP853 at 1e-12 is exact in comparison)
    np.testing.assert_allclose(states[::100], ref, atol=1e-6)
    assert states[-1, 0] - x0[0] > 4 * np.pi, "the disk turned over the top"


def test_motor_work_is_torque_times_angle(crank):
    tau = 0.8
    x0 = np.array([-0.5, 0.0])
    times, states = simulate(crank, x0, duration=1.0, dt=0.001, u=[tau])
    gain = crank.energy(states[-1]) - crank.energy(x0)
    # constant torque: work = tau * (theta_T - theta_0); RK4 at 1 ms leaves ~1e-10 J
    np.testing.assert_allclose(gain, tau * (states[-1, 0] - x0[0]), atol=1e-8)
