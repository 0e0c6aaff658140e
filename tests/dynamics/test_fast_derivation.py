"""The derivation's own machinery: differentiation rules, the shared program and its
forward-mode Jacobians, display forms formed lazily, and an independent cross-check of a
chain of links against sympy's `LagrangesMethod`."""

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

import dynamics
import dynamics.derive
from benchmarks.derivation import cart_chain  # the scaling benchmark's system
from dynamics.calculus import compact, diff
from dynamics.program import Program
from dynamics.spec import t

a, b, c = sp.symbols("a b c", real=True)
CASES = [
    a * b**2 * sp.sin(a * c),
    sp.cos(a - b) ** 3 / (1 + a**2),
    sp.sqrt(1 + a**2 * b) * c,
    (a + b * sp.cos(c)) ** 2 + sp.tan(a) * sp.exp(b),  # tan, exp: handed to sympy
    a**b + sp.Abs(a - c),
    sp.Integer(3),
]


@pytest.mark.parametrize("expr", CASES)
def test_diff_agrees_with_sympy(expr):
    rng = np.random.default_rng(0)
    for v in (a, b, c):
        ours, theirs = diff(expr, v), expr.diff(v)
        f = sp.lambdify((a, b, c), [ours, theirs])
        for point in rng.uniform(0.3, 1.5, (5, 3)):
            x, y = f(*point)
            # the same formula with terms in another order: round-off of a few terms
            assert x == pytest.approx(y, rel=1e-12, abs=1e-12)


def test_compact_expands_only_when_smaller():
    assert compact(a * b + a * (c - b)) == a * c  # like terms cancel
    assert compact((a + b + c) ** 6) == (a + b + c) ** 6  # 28 terms: kept as it is


def test_program_shares_and_differentiates_through_its_steps():
    x, y = sp.symbols("x y")
    e1 = sp.sin(x * y) ** 2 + x
    e2 = sp.sin(x * y) * sp.cos(y)
    prog = Program({"one": [e1], "two": [e2]})
    assert len(prog.needed(prog.results["two"])) >= 1  # sin(x y) assigned once, shared
    steps, J = prog.derivatives(prog.results["one"] + prog.results["two"], [x, y])
    point = {"x": 0.7, "y": -0.4}
    for sym, e in prog.needed(prog.results["one"] + prog.results["two"]) + steps:
        point[str(sym)] = float(e.subs({sp.Symbol(k): v for k, v in point.items()}))
    for row, e in zip(J, (e1, e2)):
        for d, v in zip(row, (x, y)):
            want = float(e.diff(v).subs({x: 0.7, y: -0.4}))
            got = float(sp.sympify(d).subs({sp.Symbol(k): v for k, v in point.items()}))
            assert got == pytest.approx(want, rel=1e-13)  # the chain rule in another order


@pytest.mark.slow
def test_derivation_and_code_generation_never_simplify(monkeypatch):
    from dynamics.codegen import generate

    def forbidden(*args, **kwargs):
        raise AssertionError("sympy.simplify on the hot path")

    spec = dynamics.get_model("rolling_disk").spec  # the model's own declaration may simplify
    monkeypatch.setattr(sp, "simplify", forbidden)
    d = dynamics.derive.derive(spec)
    assert "def derivative_lanes" in generate(d, "key")
    with pytest.raises(AssertionError, match="hot path"):
        d.equations  # noqa: B018  (the display forms do simplify, when asked)


@pytest.mark.slow
def test_chain_on_a_cart_equals_lagranges_method():
    """An independent route: sympy's own Lagrange derivation of the same system."""
    n = 3
    spec = cart_chain(n)
    code = dynamics.derive.derive(spec).code
    q = list(spec.coordinates)
    lm = me.LagrangesMethod(spec.kinetic - spec.potential, q, forcelist=None, frame=None)
    lm.form_lagranges_equations()
    F = sp.Symbol("F")
    lm_forcing = lm.forcing + sp.Matrix([F] + [0] * n)  # the cart force as Q_x
    plain = dict(zip([qi.diff(t) for qi in q], code.x[n + 1 :])) | dict(zip(q, code.x[: n + 1]))
    params = list(spec.parameters)
    theirs = sp.lambdify(
        list(code.x) + params + [F], [me.msubs(e, plain) for e in [*lm.mass_matrix, *lm_forcing]]
    )
    ours = sp.lambdify(list(code.x) + list(code.p) + list(code.u), [*code.mass, *code.forcing])
    rng = np.random.default_rng(3)
    for _ in range(5):
        args = [*rng.uniform(-3, 3, 2 * (n + 1)), 1.0, 0.3, 0.5, 9.81, rng.uniform(-2, 2)]
        # the same sums in another order; entries up to ~1e2 at these rates
        np.testing.assert_allclose(ours(*args), theirs(*args), rtol=1e-12, atol=1e-12)
