"""Self-stability of the upright rolling disk: linearisation vs classical result vs simulation."""

import numpy as np
import pytest

import dynamics
from dynamics import disk_stability as ds


@pytest.fixture(scope="module")
def disk():
    return dynamics.get_model("rolling_disk").compile()


def test_critical_spin_equals_thin_disk_result(disk):
    r, g = disk.parameters["r"], disk.parameters["g"]
    # the root is found to ~1e-15 by brentq on exact Jacobians; 1e-6 is the bar
    assert ds.critical_spin(disk) == pytest.approx(np.sqrt(g / (3 * r)), rel=1e-6)


def test_critical_spin_equals_general_formula_for_other_inertias(disk):
    # a thick, heavy wheel with its mass towards the rim: not the thin-disk ratios
    wheel = disk.with_parameters(m=2.0, r=0.25, I=0.05, J=0.09, g=9.81)
    expected = ds.classical_critical_spin(2.0, 0.25, 0.05, 0.09, 9.81)
    assert expected != pytest.approx(np.sqrt(9.81 / (3 * 0.25)), rel=1e-3)
    # same bar as above: root to ~1e-15, compared at the 1e-6
    assert ds.critical_spin(wheel) == pytest.approx(expected, rel=1e-6)


def test_upright_rolling_is_a_steady_motion_of_the_reduced_state(disk):
    x = ds.upright_rolling(disk, spin=-7.0, heading=0.4)
    # round-off only: the constraints and the reduced accelerations vanish identically
    np.testing.assert_allclose(disk.constraint_residual(x), 0.0, atol=1e-12)
    np.testing.assert_allclose(disk.accelerations(0.0, x, [0.0, 0.0]), 0.0, atol=1e-12)


def test_eigenvalues_unstable_below_and_neutral_above_critical(disk):
    wc = ds.critical_spin(disk)
    below, above = ds.lean_eigenvalues(disk, [0.8 * wc, 1.2 * wc])
    a = disk.parameters["m"] * disk.parameters["g"] * disk.parameters["r"] / 0.1125
    # below: a real pair +-s with s^2 = a (1 - (w/wc)^2) (the classical lean equation)
    assert below.real.max() == pytest.approx(np.sqrt(a * (1 - 0.8**2)), rel=1e-9)
    # above: an imaginary pair +-i w with w^2 = a ((w/wc)^2 - 1), no growing mode; the
    # 1e-9 bounds are round-off of a 3x3 eigenvalue problem with entries ~30
    assert np.abs(above.real).max() < 1e-9
    assert np.abs(above.imag).max() == pytest.approx(np.sqrt(a * (1.2**2 - 1)), rel=1e-9)


def test_direction_of_rolling_does_not_matter(disk):
    spins = [1.0, 4.0, 9.0]
    fwd, back = ds.lean_eigenvalues(disk, spins), ds.lean_eigenvalues(disk, np.negative(spins))
    # eigenvalues of matrices equal up to a similarity: round-off of a 3x3 problem
    np.testing.assert_allclose(np.sort_complex(fwd), np.sort_complex(back), atol=1e-9)


def test_nonlinear_rolling_departs_just_below_critical(disk):
    wc = ds.critical_spin(disk)
    t, lean = ds.simulate_lean(disk, 0.95 * wc, lean_rate0=0.05, duration=4.0)
    linear = ds.linear_lean(disk, 0.95 * wc, 0.05, t)
    small = np.abs(linear) < 0.05
    # while small the lean follows the linear exponential growth; 5e-4 rad allows the
    # cubic terms at 0.05 rad (~0.05^3) and RK4 error at dt = 5 ms (~1e-8)
    assert np.abs(lean - linear)[small].max() < 5e-4
    # ... and it then leaves upright far behind: >0.25 rad from a 0.05 rad/s kick
    # (the neutral amplitude above critical is ~0.03 rad)
    assert np.abs(lean).max() > 0.25


def test_nonlinear_rolling_stays_up_just_above_critical(disk):
    wc = ds.critical_spin(disk)
    t, lean = ds.simulate_lean(disk, 1.05 * wc, lean_rate0=0.05, duration=10.0)
    nu = np.sqrt(ds._stiffness(disk, 1.05 * wc))
    # a wobble of amplitude kick / nu; 5 % covers the nonlinear terms at ~0.03 rad
    assert np.abs(lean).max() == pytest.approx(0.05 / nu, rel=0.05)
    # its first peak at a quarter period of the linearised wobble (the sample spacing
    # of 5 ms is 0.5 % of it; 2 % also covers the amplitude-dependent frequency shift)
    first = t < np.pi / nu
    assert t[first][np.argmax(lean[first])] == pytest.approx(np.pi / (2 * nu), rel=0.02)


def test_classical_formula_rejects_non_physical_values():
    with pytest.raises(ValueError, match="J must be positive"):
        ds.classical_critical_spin(1.0, 0.3, 0.0225, 0.0, 9.81)


def test_command_line_reports_and_plots(tmp_path, capsys):
    out = tmp_path / "disk.png"
    assert ds.main(["--plot", str(out)]) == 0
    text = capsys.readouterr().out
    assert "critical spin from the linearisation: 3.3015" in text
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert list(tmp_path.iterdir()) == [out]  # written atomically: no temporary left over
