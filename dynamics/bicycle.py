"""The benchmark bicycle's linearised lean-and-steer equations, from the derived model.

Meijaard, Papadopoulos, Ruina and Schwab (2007) write the linearised equations of the
Whipple bicycle about upright straight running at forward speed v as

    M q'' + v C1 q' + (g K0 + v^2 K2) q = f,    q = (phi, delta),  f = (T_phi, T_delta)

(lean and steer; lean torque and steer torque). Here M, C1, K0, K2 come from the model
`whipple_bicycle` (derived by Lagrange's equations with multipliers): its exact Jacobians
at the steady motion give the 16-state linearisation; restricting it to perturbations that
satisfy the linearised constraints (the dependent pitch, yaw rate, contact velocities and
front wheel rate follow lean and steer) leaves four states (phi, delta, phi', delta'). The
input matrix of that reduction is M^-1; its state matrix gives v C1 and g K0 + v^2 K2,
separated by evaluating at v = 0 and v = 1 (the dependence on v is polynomial, so this is
exact; the tests check it at other speeds). Parameters are the model's names; the compiled
model comes from the cache, and its first linearisations run without compiling them
(`System.linearize`), so a call takes a fraction of a second once the model is derived.

    python -m dynamics.bicycle --plot bicycle.png   # matrices, speeds, eigenvalues (figure)
"""

from __future__ import annotations

import argparse
import io
import sys
from functools import lru_cache

import numpy as np
from scipy.optimize import brentq

from .cache import write_atomic

MODEL = "whipple_bicycle"
LEAN_STEER = ("phi", "delta")
DEPENDENT_RATES = ("x", "y", "psi", "theta", "theta_F")
"""The rates the five velocity constraints fix, given the lean, steer and rear wheel rates."""
HOLONOMIC_ROW = 4
"""The model's fifth constraint: the rate of the front contact's height, f(phi, theta, delta)."""


@lru_cache(maxsize=32)
def _system(items: tuple):
    import dynamics

    return dynamics.get_model(MODEL).compile(**dict(items))


def bicycle_system(**params):
    """The compiled `whipple_bicycle` with these parameters (from the model cache)."""
    return _system(tuple(sorted(params.items())))


def upright_state(system, speed: float) -> np.ndarray:
    """Upright straight running along N.x at forward speed `speed` (m/s): all angles 0,
    the wheels rolling (theta_R' = -v / r_R, theta_F' = -v / r_F)."""
    n = system.n_q
    i = {name: k for k, name in enumerate(system.coordinates)}
    x = np.zeros(2 * n)
    x[n + i["x"]] = speed
    x[n + i["theta_R"]] = -speed / system.parameters["r_R"]
    x[n + i["theta_F"]] = -speed / system.parameters["r_F"]
    return x


def _constraint_jacobians(system, x0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(dR/dq, dR/dqdot) of the velocity constraints R = B(q) qdot at x0, exactly.

    dR/dqdot = B is the lower block of the mass/constraint matrix. For dR/dq, the
    constraint accelerations gamma = -(d/dt B) qdot are a quadratic form in qdot
    (the constraints are homogeneous in the rates), so polarising it,
    gamma(a + b) - gamma(a) - gamma(b) = -(dB/dq a) b - (dB/dq b) a; with a = e_j and
    b = qdot0, which moves only coordinates B does not depend on (x, theta_R, theta_F),
    the second term vanishes and it is -(dB/dq_j) qdot0 = -dR/dq_j."""
    n = system.n_q
    moving = [j for j in range(n) if x0[n + j] != 0.0]
    if any(system.coordinates[j] not in ("x", "theta_R", "theta_F") for j in moving):
        raise ValueError("the operating point must move only x, theta_R and theta_F.")

    def gamma(rates):
        x = x0.copy()
        x[n:] = rates
        A, r = system.kkt(x)
        return r[n:], A[n:, :n]

    qd0 = x0[n:]
    scale = max(float(np.abs(qd0).max()), 1.0)
    g0, B = gamma(qd0)  # B: the lower block of the mass/constraint matrix
    dRdq = np.zeros((system.n_c, n))
    for j in range(n):
        e = np.zeros(n)
        e[j] = scale
        ga, _ = gamma(e)
        gab, _ = gamma(e + qd0)
        dRdq[:, j] = -(gab - ga - g0) / scale
    return dRdq, B


def reduced_linearization(system, speed: float) -> tuple[np.ndarray, np.ndarray]:
    """(A4, B2): d/dt (phi, delta, phi', delta') = A4 s + B2 (T_phi, T_delta) about upright
    straight running at `speed`, on the constraint manifold."""
    n = system.n_q
    names = system.coordinates
    idx = {c: names.index(c) for c in names}
    x0 = upright_state(system, speed)
    A, Bu = system.linearize(x0, np.zeros(system.n_u))
    dRdq, Bc = _constraint_jacobians(system, x0)
    dep = [idx[c] for c in DEPENDENT_RATES]
    pitch = idx["theta"]
    # the holonomic constraint's rate form is grad f . qdot, so its row of B is grad f
    hol = HOLONOMIC_ROW
    off = [j for j in range(n) if names[j] not in ("phi", "theta", "delta")]
    if np.abs(Bc[hol, off]).max() > 0.0:
        raise ValueError(f"{MODEL}: constraint {hol} is not the front wheel's contact height.")
    basis = []
    for which in ("q", "qd"):
        for c in LEAN_STEER:
            dq, dqd = np.zeros(n), np.zeros(n)
            (dq if which == "q" else dqd)[idx[c]] = 1.0
            dq[pitch] = -(Bc[hol] @ dq) / Bc[hol, pitch]  # stay on f = 0
            rhs = -(Bc @ dqd) - dRdq @ dq
            dqd[dep] = np.linalg.solve(Bc[:, dep], rhs)
            basis.append(np.concatenate([dq, dqd]))
    S = np.array(basis).T  # 2n x 4: the perturbations of (phi, delta, phi', delta')
    rows = [n + idx[c] for c in LEAN_STEER]
    A4 = np.zeros((4, 4))
    A4[:2, 2:] = np.eye(2)
    A4[2:] = A[rows] @ S
    inputs = [system.inputs.index(u) for u in ("T_phi", "T_delta")]
    return A4, Bu[np.ix_(rows, inputs)]


def benchmark_matrices(**params) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(M, C1, K0, K2), each 2x2 over (phi, delta), of the linearised equations
    M q'' + v C1 q' + (g K0 + v^2 K2) q = (T_phi, T_delta) of `whipple_bicycle` with these
    parameters (its names; defaults the benchmark's, Meijaard et al. 2007, Table 1)."""
    system = bicycle_system(**params)
    g = system.parameters["g"]
    stiffness, damping, masses = [], [], []
    for v in (0.0, 1.0):
        A4, B2 = reduced_linearization(system, v)
        M = np.linalg.inv(B2)
        masses.append(M)
        stiffness.append(-M @ A4[2:, :2])
        damping.append(-M @ A4[2:, 2:])
    M = (masses[0] + masses[1]) / 2
    M = (M + M.T) / 2  # symmetric in exact arithmetic (a kinetic energy's Hessian)
    return M, damping[1], stiffness[0] / g, stiffness[1] - stiffness[0]


def eigenvalues(speeds, matrices=None, g: float | None = None, **params) -> np.ndarray:
    """Eigenvalues of the uncontrolled linearised bicycle (1/s) at each forward speed,
    shape (len(speeds), 4), sorted by real part then imaginary part. `matrices` (M, C1,
    K0, K2) and `g` default to the model's with `params`."""
    if matrices is None:
        matrices = benchmark_matrices(**params)
        if g is None:
            g = bicycle_system(**params).parameters["g"]
    if g is None:
        raise ValueError("eigenvalues: give g with matrices.")
    M, C1, K0, K2 = matrices
    Minv = np.linalg.inv(M)
    out = []
    for v in np.atleast_1d(np.asarray(speeds, dtype=np.float64)):
        A = np.zeros((4, 4))
        A[:2, 2:] = np.eye(2)
        A[2:, :2] = -Minv @ (g * K0 + v * v * K2)
        A[2:, 2:] = -Minv @ (v * C1)
        ev = np.linalg.eigvals(A)
        out.append(ev[np.lexsort((ev.imag, ev.real))])
    return np.array(out)


def stable_speeds(v_max: float = 10.0, step: float = 0.05, **params) -> tuple[float, float]:
    """(weave speed, capsize speed), m/s: the ends of the self-stable range, where the
    largest real part of the eigenvalues crosses zero (the weave pair's going down, the
    capsize eigenvalue's going up), found by bisection to machine precision."""
    matrices = benchmark_matrices(**params)
    g = bicycle_system(**params).parameters["g"]

    def margin(v: float) -> float:
        return float(eigenvalues(v, matrices, g)[0].real.max())

    grid = np.arange(step, v_max + step / 2, step)
    values = [margin(v) for v in grid]
    weave = capsize = None
    for a, b, fa, fb in zip(grid[:-1], grid[1:], values[:-1], values[1:]):
        if weave is None and fa > 0 >= fb:
            weave = brentq(margin, a, b, xtol=1e-15, rtol=1e-15)
        elif weave is not None and fa < 0 <= fb:
            capsize = brentq(margin, a, b, xtol=1e-15, rtol=1e-15)
            break
    if weave is None or capsize is None:
        raise ValueError(
            f"No self-stable speed range below {v_max} m/s for {params or 'defaults'}."
        )
    return weave, capsize


def report(**params) -> str:
    """Text: the matrices, the stable speed range and eigenvalues at 0..10 m/s."""
    M, C1, K0, K2 = benchmark_matrices(**params)
    weave, capsize = stable_speeds(**params)
    fmt = {"float_kind": lambda a: f"{a: .14f}"}
    lines = [
        f"{name} =\n{np.array2string(X, formatter=fmt)}"
        for name, X in (("M", M), ("C1", C1), ("K0", K0), ("K2", K2))
    ]
    lines.append(f"weave speed {weave:.14f} m/s, capsize speed {capsize:.14f} m/s")
    lines.append("v (m/s)   eigenvalues (1/s)")
    speeds = np.arange(0.0, 10.5, 1.0)
    for v, ev in zip(speeds, eigenvalues(speeds, **params)):
        lines.append(f"{v:5.1f}   " + "  ".join(f"{e.real:+.8f}{e.imag:+.8f}j" for e in ev))
    return "\n".join(lines)


def plot(path: str, v_max: float = 10.0, **params) -> None:
    """The eigenvalues' real and imaginary parts against speed, 0..v_max m/s (the paper's
    Figure 3), with the self-stable range shaded; saved to `path`."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    speeds = np.linspace(0.0, v_max, 501)
    ev = eigenvalues(speeds, **params)
    weave, capsize = stable_speeds(v_max=v_max, **params)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for k in range(ev.shape[1]):
        ax.plot(speeds, ev[:, k].real, "C0.", ms=2, label="real part" if k == 0 else None)
        oscillating = ev[:, k].imag > 0  # one of each complex pair
        ax.plot(speeds[oscillating], ev[oscillating, k].imag, "C1.", ms=2)
    ax.plot([], [], "C1.", label="imaginary part")
    ax.axvspan(weave, capsize, color="0.9", label=f"self-stable {weave:.3f}-{capsize:.3f} m/s")
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_ylim(-10, 10)
    ax.set_xlabel("forward speed v (m/s)")
    ax.set_ylabel("eigenvalue (1/s)")
    ax.set_title("whipple_bicycle: lean and steer eigenvalues against speed")
    ax.legend(fontsize=8)
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=120)
    write_atomic(path, buffer.getvalue())
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m dynamics.bicycle",
        description="The benchmark bicycle's M, C1, K0, K2, self-stable speeds and "
        "eigenvalues, from the derived whipple_bicycle model.",
    )
    parser.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="override a whipple_bicycle parameter; repeatable",
    )
    parser.add_argument("--plot", metavar="FILE", help="save eigenvalues against speed")
    args = parser.parse_args(argv)
    params = {}
    for item in args.param:
        name, sep, value = item.partition("=")
        if not sep:
            parser.error(f"--param expects NAME=VALUE, got {item!r}")
        params[name] = float(value)
    try:
        print(report(**params))
        if args.plot:
            plot(args.plot, **params)
            print(f"saved {args.plot}")
    except ValueError as e:
        parser.error(str(e))
    return 0


if __name__ == "__main__":
    sys.exit(main())
