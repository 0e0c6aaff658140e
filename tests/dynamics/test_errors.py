"""Bad input gets an error that names the problem."""

import numpy as np
import pytest

import dynamics


@pytest.fixture(scope="module")
def arm():
    return dynamics.get_model("two_link_arm").compile()


def test_unknown_model_suggests_close_match():
    with pytest.raises(ValueError, match="Did you mean 'two_link_arm'"):
        dynamics.get_model("two_link_ram")


def test_unknown_parameter_suggests_close_match():
    with pytest.raises(ValueError, match="Unknown parameter 'mm1'.*Did you mean 'm1'"):
        dynamics.get_model("two_link_arm").compile(mm1=2.0)


@pytest.mark.parametrize("name,value", [("m1", 0.0), ("l", -1.0), ("Ibar2", -0.1), ("g", 0.0)])
def test_non_positive_physical_parameter_is_rejected(name, value):
    with pytest.raises(ValueError, match=f"'{name}'.*must be positive"):
        dynamics.get_model("two_link_arm").compile(**{name: value})


def test_non_numeric_and_nan_parameters_are_rejected():
    with pytest.raises(TypeError, match="'m1'.*must be a number"):
        dynamics.get_model("two_link_arm").compile(m1="heavy")
    with pytest.raises(ValueError, match="'l'.*finite"):
        dynamics.get_model("two_link_arm").compile(l=float("nan"))


def test_wrong_state_shape(arm):
    with pytest.raises(ValueError, match=r"state of shape \(\.\.\., 4\).*got \(3,\)"):
        arm.state_derivative(0.0, np.zeros(3), np.zeros(2))


def test_wrong_input_shape(arm):
    with pytest.raises(ValueError, match=r"input of shape \(\.\.\., 2\).*got \(3,\)"):
        arm.state_derivative(0.0, np.zeros(4), np.zeros(3))


def test_incompatible_batch_shapes(arm):
    with pytest.raises(ValueError):
        arm.state_derivative(0.0, np.zeros((3, 4)), np.zeros((2, 2)))


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_state_input_time(arm, bad):
    x = np.zeros(4)
    x[1] = bad
    with pytest.raises(ValueError, match="state contains NaN or inf"):
        arm.state_derivative(0.0, x, np.zeros(2))
    with pytest.raises(ValueError, match="input contains NaN or inf"):
        arm.step(np.zeros(4), np.array([0.0, bad]), 0.01)
    with pytest.raises(ValueError, match="time contains NaN or inf"):
        arm.energy(np.zeros(4), t=bad)


def test_bad_step_arguments(arm):
    with pytest.raises(ValueError, match="dt must be a positive"):
        arm.step(np.zeros(4), np.zeros(2), dt=0.0)
    with pytest.raises(ValueError, match="substeps must be a positive integer"):
        arm.step(np.zeros(4), np.zeros(2), dt=0.01, substeps=0)


def test_non_pfaffian_constraint_is_rejected():
    import sympy as sp
    import sympy.physics.mechanics as me

    from dynamics.spec import ModelSpec, Param, t

    x, y = me.dynamicsymbols("x y")
    m = sp.Symbol("m", positive=True)
    spec = ModelSpec(
        name="bad",
        coordinates=(x, y),
        kinetic=m * (x.diff(t) ** 2 + y.diff(t) ** 2) / 2,
        potential=sp.S.Zero,
        parameters={m: Param(1.0, "kg")},
        constraints=(x.diff(t) ** 2 - y.diff(t),),
    )
    with pytest.raises(ValueError, match="linear in the coordinate rates"):
        dynamics.Model(spec).equations()


def test_model_specific_parameter_conditions_are_checked():
    # the crank of problem 7/3 locks unless the rod is longer than R + |h|
    with pytest.raises(ValueError, match=r"violate l > R \+ \|h\|"):
        dynamics.get_model("eccentric_disk_slider").compile(l=0.1, R=0.1)
    with pytest.raises(ValueError, match=r"violate l > R \+ \|h\|"):
        dynamics.get_model("eccentric_disk_slider").compile(h=-0.25)
    dynamics.get_model("eccentric_disk_slider").compile(h=-0.15)  # 0.3 > 0.1 + 0.15
