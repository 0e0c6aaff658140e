"""Identification a user can trust: the noise told from the record, what a record does not
determine kept at its given value and named, and nothing impossible written.

Records are made with the plant's own compiled model (`simulate`, 10 substeps per sample)
with Gaussian sensor noise added; "right" is the issue's statement of it: the truth within
3 standard errors, and that standard error at most 25 % of the value."""

from __future__ import annotations

import numpy as np
import pytest

import dynamics
from dynamics import regression
from dynamics.excite import multisine
from dynamics.identify import REL_STD, identify
from dynamics.regression import with_noise

from .test_identify import ARM, simulate


def assert_right_or_flagged(fit, truth):
    for name, value in truth.items():
        if name in fit.undetermined:  # flagged: kept at its given value, named
            continue
        s = fit.std[name]
        assert s <= REL_STD * abs(fit.parameters[name]), (name, s)
        assert abs(fit.parameters[name] - value) <= 3 * s, (name, fit.parameters[name], s)
        assert abs(fit.parameters[name] / value - 1) <= 0.25, name


@pytest.fixture(scope="module")
def arm():
    return dynamics.get_model("two_link_arm")


@pytest.fixture(scope="module")
def fast_arm(arm):
    """The arm driven hard: rates up to about 45 rad/s at 100 Hz."""
    data = simulate(arm.compile(**ARM), [0.1, 0.2, 0.0, 0.0], [14.0, 6.0], fraction=0.9)
    assert np.abs(data["qd"]).max() > 30
    return data


def test_noise_std_is_told_from_a_record_and_refused_where_the_motion_hides_it(fast_arm):
    """White noise of std 1e-2 on the fast arm's rates is told within 25 % at 100 Hz
    (measured 11-16 %: the robust estimator's spread on 2000 samples and the motion's
    residue); the same record at 20 Hz has steps where the motion's differences are as
    large as the noise's, and the estimator says it cannot tell."""
    rates = with_noise(fast_arm, (0.0, 1e-2))["qd"]
    sigma, told = regression.noise_std(rates)
    assert told.all() and sigma == pytest.approx([1e-2, 1e-2], rel=0.25)
    sigma, told = regression.noise_std(fast_arm["qd"])  # noise-free: nothing white to see
    assert not told.any() or (sigma < 1e-6 * np.abs(fast_arm["qd"]).max()).all()
    _, told = regression.noise_std(rates[::5])
    assert not told.all()


@pytest.mark.parametrize("std", [(1e-3, 1e-2), (3e-3, 5e-2)])
def test_fast_arm_with_noise_not_given_is_right(arm, fast_arm, std):
    """Noise left to the library on the fast arm (the issue: +290 % to +764 %, intervals
    as wide as the values): every inertial parameter right by the issue's test."""
    fit = identify(arm, with_noise(fast_arm, std))
    assert "estimated" in fit.noise
    assert_right_or_flagged(fit, ARM)
    assert fit.undetermined == {}


@pytest.mark.slow  # the disk's record and smoothed fit: ~4 s
def test_rolling_disk_with_noise_not_given_is_right_or_flagged():
    disk = dynamics.get_model("rolling_disk")
    true = dict(m=1.4, I=0.03, J=0.05)
    system = disk.compile(**true)
    x0 = system.project(np.array([0, 0, np.pi / 2, 0, 0, 0, 0, 0, 0, -15.0]))
    data = simulate(system, x0, [0.1, 0.02])
    for std in ((1e-3, 1e-2), (3e-3, 5e-2)):
        fit = identify(disk, with_noise(data, std))
        assert_right_or_flagged(fit, true)
        p = fit.parameters
        assert p["J"] <= 2 * p["I"] * (1 + 1e-9)  # a disk: J = 2 I at most (flat)


@pytest.mark.slow
def test_what_the_record_does_not_determine_is_kept_and_named(arm):
    """The shoulder held still by a stiff servo (its torque recorded), the elbow driven:
    Ibar1 multiplies the shoulder's acceleration, which stays zero, so the record cannot
    tell it. It is kept at its given value and listed with the reason, never written as a
    fitted number (before: m1 = 1e-9 +- 30); m1 still shows through the shoulder's
    gravity torque and is estimated."""
    system = arm.compile(**ARM)
    h, T = 0.01, 2001
    t = np.arange(T) * h
    elbow = multisine([3.0], period=10.0, harmonics=4, fraction=0.5)(t)[:, 0]
    x, X, U = np.array([0.3, 0.2, 0.0, 0.0]), [], []
    for k in range(T):
        u = np.array([-2000 * (x[0] - 0.3) - 90 * x[2], elbow[k]])
        X.append(x)
        U.append(u)
        x = system.step(x, u, dt=h, substeps=10)
    X = np.array(X)
    data = with_noise({"t": t, "q": X[:, :2], "qd": X[:, 2:], "u": np.array(U)}, (1e-3, 1e-2))
    fit = identify(arm, data)
    assert "Ibar1" in fit.undetermined and "kept at its given value" in fit.undetermined["Ibar1"]
    assert fit.parameters["Ibar1"] == arm.parameters["Ibar1"]
    assert np.isnan(fit.std["Ibar1"]) and "Ibar1" not in fit.precision
    assert_right_or_flagged(fit, ARM)


@pytest.fixture(scope="module")
def slow_arm(arm):
    return simulate(arm.compile(**ARM), [0.1, 0.2, 0.0, 0.0], [6.0, 3.0], seconds=4.0)


def _with(record, key, change):
    out = {k: np.array(v, copy=True) for k, v in record.items()}
    out[key] = change(out[key])
    return out


def _nan_at(a):
    a[5, 0] = np.nan
    return a


BAD = [  # (what, record change or None, keyword arguments, the message's words)
    ("complex positions", ("q", lambda a: a + 0j), {}, "data['q']: complex numbers"),
    ("text rates", ("qd", lambda a: a.astype(str)), {}, "data['qd']: text"),
    ("a NaN", ("q", _nan_at), {}, "data['q']: nan at (5, 0)"),
    ("huge values", ("qd", lambda a: a * 1e300), {}, "of magnitude"),
    ("milliseconds as seconds", ("t", lambda a: a * 1000), {}, "milliseconds given as seconds"),
    ("seconds as milliseconds", ("t", lambda a: a / 1000), {}, "times the model's"),
    ("no motion", None, {"data": "still"}, "does not move"),
    ("no input", ("u", lambda a: a * 0), {}, "tells their ratios, not their scale"),
    ("a negative mass given", None, {"given": {"m1": -1.0}}, "given:"),
    ("a NaN given", None, {"given": {"m1": float("nan")}}, "given: m1 = nan"),
    ("text given", None, {"given": {"m1": "heavy"}}, "given: m1 = 'heavy'"),
    ("no unknowns", None, {"unknown": []}, "unknown: empty"),
    ("noise NaN", None, {"noise": (float("nan"), 0.0)}, "noise: two stds >= 0"),
    ("noise a word", None, {"noise": "low"}, "noise: two stds >= 0"),
    ("noise negative", None, {"noise": (-1.0, 0.0)}, "noise: two stds >= 0"),
]


@pytest.mark.parametrize("what, change, kwargs, words", BAD, ids=[b[0] for b in BAD])
def test_bad_records_and_arguments_are_refused_in_one_line(arm, slow_arm, what, change, kwargs,
                                                           words):  # fmt: skip
    data = slow_arm if change is None else _with(slow_arm, *change)
    kwargs = dict(kwargs)
    if kwargs.pop("data", None) == "still":
        data = slow_arm | {"q": np.zeros_like(slow_arm["q"]), "qd": np.zeros_like(slow_arm["qd"])}
    with pytest.raises(ValueError) as err:
        identify(arm, data, **kwargs)
    message = str(err.value)
    assert words in message and "\n" not in message, message


def test_only_nonlinear_unknowns_are_refined_by_simulation_error(arm, slow_arm):
    """l1 alone (it enters squared): no linear fit to make, simulation error alone (before:
    'cannot reshape array of size 0')."""
    fit = identify(arm, slow_arm, unknown=["l1"], given=ARM | {"l1": 0.45})
    assert fit.parameters["l1"] == pytest.approx(0.5, rel=1e-3)


def test_positions_only_sampled_too_slowly_for_the_motion_is_warned(arm, fast_arm):
    """The fast arm's positions at 20 Hz: the cubic filter flattens its rates (the fit comes
    out 17-39 % off); the result and a warning say so. At 100 Hz, recorded rates: none."""
    slow = {k: fast_arm[k][::5] for k in ("t", "q", "u")}
    with pytest.warns(UserWarning, match="positions only at 20 Hz"):
        fit = identify(arm, slow)
    assert fit.warnings and "sample faster" in fit.warnings[0]
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert identify(arm, fast_arm).warnings == []


def test_friction_declared_on_a_joint_acts_on_its_relative_rate(arm):
    """The arm's coordinates are absolute angles; its elbow's friction acts on the relative
    rate theta2' - theta1' (torque tau on the elbow: -tau on theta1, +tau on theta2).
    Declared on the joint, the plant's coefficients and inertias come back right by the
    issue's test, with noise (1e-3, 1e-2) left to the library."""
    from dynamics.regressor import with_friction

    joints = {"shoulder": ("theta1", "viscous+coulomb"),
              "elbow": ("theta2 - theta1", "viscous+coulomb")}  # fmt: skip
    friction = {"viscous_shoulder": 0.1, "coulomb_shoulder": 0.3,
                "viscous_elbow": 0.08, "coulomb_elbow": 0.25}  # fmt: skip
    plant = with_friction(arm, joints).compile(**ARM, **friction)
    data = with_noise(simulate(plant, [0.1, 0.2, 0.0, 0.0], [6.0, 3.0], fraction=0.8), (1e-3, 1e-2))
    fit = identify(arm, data, friction=joints)
    assert set(fit.friction) == {"shoulder", "elbow"}
    est = dict(fit.parameters)
    for joint, values in fit.friction.items():
        est |= {f"{kind}_{joint}": v for kind, v in values.items()}
    assert_right_or_flagged(type(fit)(**{**fit.__dict__, "parameters": est}), ARM | friction)
    assert not set(ARM) & set(fit.undetermined)


@pytest.mark.parametrize(
    "friction, words",
    [
        ({"elbow": ("theta2 - theta3", "viscous")}, "no coordinate 'theta3'"),
        ({"elbow": ("theta2 ** 2", "viscous")}, "not a linear combination"),
        ({"elbow": ("theta2 - theta2", "viscous")}, "is zero"),
        ({"theta1": ("theta2 - theta1", "viscous")}, "not a coordinate's"),
        ({"elbow": ("theta2 - theta1", "sticky")}, "must be one of"),
    ],
)
def test_bad_joint_friction_is_refused_by_name(arm, slow_arm, friction, words):
    with pytest.raises(ValueError, match=words):
        identify(arm, slow_arm, friction=friction)
