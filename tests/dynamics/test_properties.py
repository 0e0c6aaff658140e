"""Property-based checks of the argument rule (dynamics/checks.py, dynamics/system.py): every
input is accepted as documented or rejected by a ValueError or TypeError that names the
argument, and no result is NaN or inf."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import dynamics
from dynamics.checks import MAX_SUBSTEPS, PARAMETER_RANGE

SETTINGS = settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)

# numbers of every kind the methods may meet: ordinary, huge, tiny, NaN/inf, complex, bools
REALS = st.floats(allow_nan=True, allow_infinity=True) | st.sampled_from(
    [0.0, 1.0, -2.5, 1e-300, 1e200, -1e300, 1e308]
)
ODD = st.sampled_from([1 + 2j, 0j, True, "1.0", None])
NUMBER = REALS | ODD | st.integers(-(2**70), 2**70)


def _named(exc: Exception, *names: str) -> bool:
    return any(name in str(exc) for name in names)


@pytest.fixture(scope="module")
def arm():
    return dynamics.get_model("two_link_arm").compile()


@pytest.fixture(scope="module")
def disk():
    return dynamics.get_model("rolling_disk").compile()


def _vector(n):
    return st.lists(REALS, min_size=n, max_size=n) | st.lists(NUMBER, min_size=n, max_size=n)


@SETTINGS
@given(name=st.sampled_from(["m1", "l", "g", "Ibar2"]), value=NUMBER)
def test_compile_accepts_documented_parameters_and_names_the_rest(name, value):
    model = dynamics.get_model("two_link_arm")
    try:
        system = model.compile(**{name: value})
    except (ValueError, TypeError) as exc:
        assert _named(exc, repr(name)), exc
        return
    v = system.parameters[name]
    assert isinstance(value, (int, float)) and not isinstance(value, bool)
    assert np.isfinite(v) and v > 0 and PARAMETER_RANGE[0] <= v <= PARAMETER_RANGE[1]


def _check(call, *names):
    """Run `call`: a finite result, or an error naming one of `names` (or the singular
    mass/constraint matrix, or the argument out of range)."""
    try:
        result = call()
    except (ValueError, TypeError) as exc:
        assert _named(exc, *names, "singular"), exc
        return None
    for part in result if isinstance(result, tuple) else (result,):
        assert np.isfinite(part).all()
    return result


@SETTINGS
@given(x=_vector(4), u=_vector(2), t=NUMBER)
def test_arm_methods_are_finite_or_name_the_argument(arm, x, u, t):
    names = ("state", "input", "time")
    _check(lambda: arm.state_derivative(t, x, u), *names)
    _check(lambda: arm.energy(x, t), "state", "time")
    _check(lambda: arm.linearize(x, u, t), *names)
    _check(lambda: arm.constraint_residual(x, t), "state", "time")
    _check(lambda: arm.project(x, t), "state", "time")


@SETTINGS
@given(
    x=_vector(4),
    dt=NUMBER,
    substeps=st.integers(-3, 2**65) | st.sampled_from([1, 2, MAX_SUBSTEPS, 2.0, True, None]),
)
def test_step_is_finite_or_names_the_argument(arm, x, dt, substeps):
    if isinstance(substeps, int) and not isinstance(substeps, bool) and substeps > 100:
        substeps = substeps if substeps > MAX_SUBSTEPS else 100  # keep the run short
    _check(lambda: arm.step(x, [0.1, -0.2], dt, substeps), "state", "dt", "substeps")


@SETTINGS
@given(
    theta=st.floats(-1.0, 4.0) | st.sampled_from([0.0, 1e-9, np.pi]),
    rates=st.lists(st.floats(-50, 50), min_size=5, max_size=5),
)
def test_disk_near_its_singular_states_is_finite_or_says_singular(disk, theta, rates):
    x = np.array([0.0, 0.0, theta, 1.5, 0.0, *rates])
    _check(lambda: disk.state_derivative(0.0, x, [0.0, 0.0]), "state")
    _check(lambda: disk.project(x), "state")
    _check(lambda: disk.step(x, [0.1, 0.0], 0.01, 2), "state", "dt")
    _check(lambda: disk.constraint_residual(x), "state")
