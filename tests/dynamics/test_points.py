"""Points of a model that external forces act on (`ModelSpec.points`): their generalised
forces by virtual work against hand-written geometry, and the integrator that adds
generalised forces (`System.step_unchecked` given W): none added is no change, and their
work is the energy they add."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

import dynamics
from dynamics.spec import ModelSpec, Param


def test_a_force_at_the_arms_points_maps_to_the_jacobian_transpose_of_its_geometry():
    """The compiled virtual work against the arm's link geometry written out by hand
    (N.x down, N.y horizontal): D = l e(theta1) + l2 e(theta2), C = l e(theta1),
    e(a) = (cos a, sin a); Q = J(q)^T f. Both are exact: 1e-12 is rounding."""
    system = dynamics.get_model("two_link_arm").compile()
    p = system.parameters
    rng = np.random.default_rng(0)
    x = rng.uniform(-3, 3, (50, 4))
    f = rng.normal(0, 10, (50, 2))
    th1, th2 = x[:, 0], x[:, 1]
    d1 = p["l"] * np.stack([-np.sin(th1), np.cos(th1)], axis=1)  # dD/dtheta1 = dC/dtheta1
    d2 = p["l2"] * np.stack([-np.sin(th2), np.cos(th2)], axis=1)
    link2 = np.stack([(f * d1).sum(1), (f * d2).sum(1)], axis=1)
    elbow = np.stack([(f * d1).sum(1), np.zeros(50)], axis=1)
    assert np.allclose(system.point_forces(x, "link2", f), link2, rtol=1e-12, atol=1e-12)
    assert np.allclose(system.point_forces(x, "elbow", f), elbow, rtol=1e-12, atol=1e-12)
    with pytest.raises(ValueError, match="Did you mean 'elbow'"):
        system.point_forces(x, "elbw", f)
    with pytest.raises(ValueError, match="2 components"):
        system.point_forces(x, "elbow", np.ones(3))


def test_a_model_declares_its_points_with_their_components():
    q = me.dynamicsymbols("q")
    m = sp.Symbol("m", positive=True)
    kwargs = dict(name="slide", coordinates=(q,), kinetic=m * q.diff() ** 2 / 2,
                  potential=sp.S.Zero, parameters={m: Param(1.0, "kg")})  # fmt: skip
    with pytest.raises(ValueError, match="column Matrix of 2 or 3"):
        ModelSpec(**kwargs, points={"block": sp.Matrix([q.diff()])})
    with pytest.raises(ValueError, match="not an identifier"):
        ModelSpec(**kwargs, points={"the block": sp.Matrix([q.diff(), 0])})
    plain = ModelSpec(**kwargs)
    assert ModelSpec(**kwargs, points={}).fingerprint() == plain.fingerprint()


def test_a_force_on_the_bead_maps_along_and_across_its_rod():
    """Bead at r (cos phi, sin phi): Q_r = f . (cos phi, sin phi), Q_phi = f . r (-sin phi,
    cos phi); exact, 1e-12 is rounding."""
    system = dynamics.get_model("bead_on_driven_rod").compile()
    rng = np.random.default_rng(1)
    x = rng.uniform(-1, 1, (20, 4))
    f = rng.normal(0, 3, (20, 2))
    r, phi = x[:, 0], x[:, 1]
    along = np.stack([np.cos(phi), np.sin(phi)], axis=1)
    across = r[:, None] * np.stack([-np.sin(phi), np.cos(phi)], axis=1)
    expected = np.stack([(f * along).sum(1), (f * across).sum(1)], axis=1)
    assert np.allclose(system.point_forces(x, "bead", f), expected, rtol=1e-12, atol=1e-12)


# the disk's pushed and per-copy lanes compile for this test alone (about 5 s of CPU): -m slow
@pytest.mark.parametrize(
    "model", ["two_link_arm", pytest.param("rolling_disk", marks=pytest.mark.slow)]
)
@pytest.mark.parametrize("rows", [1, 9])  # one row at a time, and vector lanes
def test_the_pushed_step_adds_the_work_of_its_forces_and_nothing_without_them(model, rows):
    """W = 0 steps bit for bit as the step without forces; with held generalised forces W
    the energy changes by W . (q1 - q0), their work (zero input, conservative models, the
    rolling constraints do no work). DOP853, 10 substeps of 5 ms: energy errors ~1e-12 J
    per step, so 1e-9 J separates a wrong force by orders of magnitude (the work is ~0.1 J)."""
    system = dynamics.get_model(model).compile()
    rng = np.random.default_rng(2)
    n = system.n_q
    x = system.project(
        rng.uniform(-0.3, 0.3, (rows, 2 * n)) + (0, 0, 1.3, 0, 0, 0, 0, 0, 0, 0)[: 2 * n]
    )
    T, U = np.zeros(rows), np.zeros((rows, system.n_u))
    P = np.tile(system.parameter_vector, (rows, 1))
    plain, pushed = np.empty_like(x), np.empty_like(x)
    system.step_unchecked(T, x, U, 0.05, 10, plain, "dop853", P=P)
    system.step_unchecked(T, x, U, 0.05, 10, pushed, "dop853", P=P, W=np.zeros((rows, n)))
    assert np.array_equal(plain, pushed)
    force = rng.normal(0, 5, (rows, system.points[next(iter(system.points))]))
    W = system.point_forces(x, next(iter(system.points)), force)
    system.step_unchecked(T, x, U, 0.05, 10, pushed, "dop853", P=P, W=W)
    work = np.einsum("bi,bi->b", W, pushed[:, :n] - x[:, :n])
    gained = system.energy(pushed) - system.energy(x)
    assert np.abs(gained - work).max() < 1e-9
    assert np.abs(work).max() > 1e-3
