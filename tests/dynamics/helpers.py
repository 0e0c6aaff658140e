"""Random states for the scleronomic models of issue 2 (shared by the dynamics tests)."""

import numpy as np

import dynamics


def random_states(name: str, count: int, seed: int = 0) -> tuple[dynamics.System, np.ndarray]:
    """`count` states: angles anywhere, rates up to a few rad/s (the disk: rolling upright-ish
    fast enough not to fall within 10 s, so that its motion stays regular)."""
    system = dynamics.get_model(name).compile()
    rng = np.random.default_rng(seed)
    n = system.n_q
    x = np.zeros((count, 2 * n))
    x[:, :n] = rng.uniform(-np.pi, np.pi, (count, n))
    x[:, n:] = rng.uniform(-3.0, 3.0, (count, n))
    if name == "rolling_disk":
        x[:, n : n + 2] = 0.0  # the projection below supplies the rolling xdot, zdot
    if name == "rolling_disk":
        x[:, 2] = np.pi / 2 + rng.uniform(-0.1, 0.1, count)
        x[:, n + 2] = rng.uniform(-0.5, 0.5, count)
        x[:, n + 3] = rng.uniform(-1.0, 1.0, count)
        x[:, n + 4] = rng.uniform(-20.0, -10.0, count)
        x = system.project(x)  # xdot, zdot consistent with rolling (eqs. 7.27-7.28)
    if name == "bead_on_driven_rod":
        x[:, 0] = rng.uniform(-0.8, 0.8, count)
    return system, x


SCLERONOMIC = ["two_link_arm", "rolling_disk", "bead_on_driven_rod"]


def book_residuals(model, exprs, count: int = 6, seed: int = 0, rates: float = 2.0) -> np.ndarray:
    """Equations from the book, each `= 0`, evaluated at `count` random states with the
    accelerations and multipliers of the compiled system: a numeric check of equations
    that a symbolic test proves at length (no derivation: the system comes from the cache).

    `exprs` may use the model's coordinates (dynamicsymbols) and their first and second
    time derivatives, `t`, the parameters, inputs and multipliers lambda1, lambda2, ...
    Returns the residuals, shape (count, len(exprs))."""
    import sympy as sp
    import sympy.physics.mechanics as me

    from dynamics.spec import t

    system = model.compile()
    spec = model.spec
    q = list(spec.coordinates)
    n = len(q)
    plain = sp.symbols(f"q0:{n}"), sp.symbols(f"qd0:{n}"), sp.symbols(f"qdd0:{n}")
    subs = {qi.diff(t, 2): s for qi, s in zip(q, plain[2])}
    subs |= {qi.diff(t): s for qi, s in zip(q, plain[1])}
    subs |= {qi: s for qi, s in zip(q, plain[0])}
    lam = sp.symbols(f"lambda1:{system.n_c + 1}")
    args = [t, *plain[0], *plain[1], *plain[2], *spec.inputs, *lam, *spec.parameters]
    f = sp.lambdify(args, [me.msubs(sp.sympify(e), subs) for e in exprs], "numpy")
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        x = np.concatenate([rng.uniform(0.2, 1.4, n), rng.uniform(-rates, rates, n)])
        x = system.project(x)
        u = rng.uniform(-1.0, 1.0, system.n_u)
        time = rng.uniform(0.0, 2.0)
        qdd, lam_values = system.accelerations(time, x, u), system.multipliers(time, x, u)
        values = [time, *x, *qdd, *u, *lam_values, *system.parameters.values()]
        out.append(np.asarray(f(*values), dtype=float))
    return np.array(out)
