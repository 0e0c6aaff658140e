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


# ---- issue 11: one conversion rule for every number, finite results or a named error ----


@pytest.mark.parametrize(
    "call,label",
    [
        (lambda s: s.state_derivative(0.0, np.array([0.1 + 1j, 0, 0, 0]), np.zeros(2)), "state"),
        (lambda s: s.state_derivative(0.0, np.zeros(4), np.array([1j, 0.0])), "input"),
        (lambda s: s.energy(np.zeros(4), t=1 + 0j), "time"),
        (lambda s: s.step(np.zeros(4), np.zeros(2), dt=0.01 + 0j), "dt"),
        (lambda s: s.linearize(np.zeros(4), np.zeros(2), t=2j), "time"),
    ],
)
def test_complex_arguments_are_rejected_by_name(arm, call, label):
    with pytest.raises(TypeError, match=f"{label} must be real"):
        call(arm)


def test_complex_boolean_and_text_parameters_are_rejected():
    model = dynamics.get_model("two_link_arm")
    for bad in (1 + 2j, np.complex128(2.0), True, "2.0"):
        with pytest.raises(TypeError, match="'m1'.*must be a number"):
            model.compile(m1=bad)


@pytest.mark.parametrize("value", [1e300, 1e51, -1e60, 1e-60])
def test_parameters_beyond_the_stated_range_are_rejected(value):
    with pytest.raises(ValueError, match=r"'l'.*out of range.*1e-50\.\.1e\+50"):
        dynamics.get_model("two_link_arm").compile(l=value)


@pytest.mark.parametrize(
    "call,method,label",
    [
        (lambda s: s.step(np.zeros(4), [1e300, 0.0], 0.01), "step", "input"),
        (lambda s: s.step(np.full(4, 1e200), None, 0.01), "step", "state"),
        (lambda s: s.step([1.0, 0, 0, 0], None, dt=1e300), "step", "dt"),
        (lambda s: s.energy(np.full(4, 1e200)), "energy", "state"),
        (lambda s: s.state_derivative(0.0, [0, 0, 1e200, 0], [0, 0]), "state_derivative", "state"),
        (lambda s: s.linearize(np.full(4, 1e300), [0, 0]), "linearize", "state"),
    ],
)
def test_finite_arguments_that_overflow_name_method_and_argument(arm, call, method, label):
    with pytest.raises(ValueError, match=rf"two_link_arm\.{method}: .*{label} is out of range"):
        call(arm)


def test_linearize_rejects_nan_time_like_energy(arm):
    for f in (
        lambda: arm.linearize(np.zeros(4), np.zeros(2), t=np.nan),
        lambda: arm.energy(np.zeros(4), t=np.nan),
    ):
        with pytest.raises(ValueError, match="time contains NaN or inf"):
            f()
    with pytest.raises(ValueError, match="no batch axis"):
        arm.linearize(np.zeros((2, 4)), np.zeros(2))


@pytest.mark.parametrize("substeps", [2**62, 2**63, 2**64, 10**6 + 1, -1])
def test_substeps_are_bounded(arm, substeps):
    with pytest.raises(ValueError, match="substeps must be a positive integer of at most"):
        arm.step(np.zeros(4), np.zeros(2), dt=0.01, substeps=substeps)


@pytest.mark.parametrize("substeps", [True, 2.0, 2.5, "3", None])
def test_substeps_must_be_an_integer(arm, substeps):
    with pytest.raises(TypeError, match="substeps must be an integer"):
        arm.step(np.zeros(4), np.zeros(2), dt=0.01, substeps=substeps)


@pytest.mark.parametrize("dt", [True, "0.01", [0.01], None])
def test_dt_must_be_a_real_number(arm, dt):
    with pytest.raises(TypeError, match="dt must be"):
        arm.step(np.zeros(4), np.zeros(2), dt=dt)


def test_get_model_with_a_non_string_name():
    with pytest.raises(TypeError, match="name must be a model name"):
        dynamics.get_model(None)


SINGULAR = [
    # a heavy second link (m2 = 1e40 kg, in range) with the links aligned: cond(M) ~ 1e40
    ("two_link_arm", {"m2": 1e40}, [0.3, 0.3, 0.0, 0.0], [0.3, -1.0, 0.0, 0.0]),
    # the disk lying flat: phi and psi both turn it about the vertical (gimbal lock)
    ("rolling_disk", {}, [0, 0, 0, 1.5, 0, 0, 0, 0, 0, 0], [0, 0, 1.5, 0, 0, 0, 0, 0, 0, -10]),
]


@pytest.mark.parametrize("name,params,x,good", SINGULAR)
def test_singular_mass_matrix_is_named_not_zero_division(name, params, x, good):
    u = [0.0, 0.0]
    system = dynamics.get_model(name).compile(**params)
    calls = [
        ("state_derivative", lambda: system.state_derivative(0.0, x, u)),
        ("state_derivative", lambda: system.state_derivative(0.0, np.tile(x, (600, 1)), u)),
        ("step", lambda: system.step(x, u, 0.01)),
        ("linearize", lambda: system.linearize(x, u)),
        ("accelerations", lambda: system.accelerations(0.0, x, u)),
    ]
    for method, call in calls:
        with pytest.raises(ValueError, match=rf"{method}: .*mass/constraint matrix is singular"):
            call()


@pytest.mark.parametrize("name,params,x,good", SINGULAR)
def test_step_unchecked_leaves_nan_in_singular_rows_only(name, params, x, good):
    system = dynamics.get_model(name).compile(**params)
    X = np.ascontiguousarray(np.stack([x, system.project(good)], dtype=np.float64))
    out = np.empty_like(X)
    system.step_unchecked(np.zeros(2), X, np.zeros((2, system.n_u)), 0.01, 2, out)
    assert np.isnan(out[0]).all()
    assert np.isfinite(out[1]).all()
