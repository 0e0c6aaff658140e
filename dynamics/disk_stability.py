"""Self-stability of the upright rolling disk: eigenvalues against spin rate, critical speed.

Upright rolling (theta = pi/2, phi' = 0, psi' = Omega constant) is a steady motion, not an
equilibrium: x, z, phi and psi keep changing. None of them appears in the equations of motion
(they are cyclic), and x', z' are fixed by the rolling constraints, so the motion is an
equilibrium of the reduced state (theta, theta', phi', psi'). At upright rolling psi' is
decoupled to first order, which leaves the lean-heading subsystem (theta, theta', phi').

Classical result (derived here for general I, J). Write eps = theta - pi/2. The rolling
contact makes the angular momentum about the contact line and about the vertical through the
contact the natural balances; to first order about upright rolling at spin psi' = Omega:

    lean:     (I + m r^2) eps''  =  m g r eps  -  (J + m r^2) Omega phi'
    heading:  I phi''            =  J Omega eps'

(gravity topples; the gyroscopic moment of the spin, J Omega, plus the centripetal term of the
contact force, m r^2 Omega, right the disk when it turns; turning is the precession the lean
rate drives). Integrating the heading equation, I phi' = J Omega eps + const, and
substituting leaves

    (I + m r^2) eps'' = [m g r - J (J + m r^2) Omega^2 / I] eps,

so the lean does not grow iff Omega^2 > Omega_c^2 = m g r I / (J (J + m r^2)). For a thin
uniform disk (I = m r^2 / 4, J = m r^2 / 2) that is Omega^2 > g / (3 r). The signs above are
those of this package's rolling_disk model (its A matrix reads them off); `critical_spin`
finds the same boundary numerically from the exact Jacobians, without this formula.

    python -m dynamics.disk_stability --plot disk_stability.png
"""

from __future__ import annotations

import argparse
import io
import sys

import numpy as np
from scipy.optimize import brentq

from .cache import write_atomic

LEAN_STATES = ("theta", "theta_dot", "phi_dot")
"""The reduced state whose stability decides upright rolling."""

KICK = 0.05
"""Lean rate (rad/s) of the disturbance in the nonlinear checks."""


def classical_critical_spin(m: float, r: float, I: float, J: float, g: float) -> float:
    """Omega_c = sqrt(m g r I / (J (J + m r^2))), rad/s: the spin rate about the axle above
    which upright rolling is self-stable (thin uniform disk: sqrt(g / (3 r)))."""
    for name, value in dict(m=m, r=r, I=I, J=J, g=g).items():
        if not value > 0:
            raise ValueError(f"{name} must be positive, got {value}.")
    return float(np.sqrt(m * g * r * I / (J * (J + m * r * r))))


def upright_rolling(system, spin: float, heading: float = 0.0) -> np.ndarray:
    """Full state of upright rolling with spin rate psi' = `spin` (rad/s) along `heading`:
    contact velocity -r psi' i' (the rolling constraints), forward speed -r psi'."""
    if not np.isfinite(spin):
        raise ValueError(f"spin must be finite, got {spin}.")
    r = system.parameters["r"]
    x = np.zeros(system.state_size)
    names = system.coordinates
    n = system.n_q
    x[names.index("theta")] = np.pi / 2
    x[names.index("phi")] = heading
    x[n + names.index("psi")] = spin
    x[n + names.index("x")] = -r * spin * np.sin(heading)
    x[n + names.index("z")] = -r * spin * np.cos(heading)
    return x


def lean_matrix(system, spin: float) -> np.ndarray:
    """A of the lean-heading subsystem (theta, theta', phi') at upright rolling with spin
    `spin`, from the exact Jacobians; the reduction is exact (checked: no dropped
    component drives a kept one)."""
    A, _ = system.linearize(upright_rolling(system, spin))
    names = list(system.coordinates) + [f"{c}_dot" for c in system.coordinates]
    keep = [names.index(s) for s in LEAN_STATES]
    dropped = [i for i in range(len(names)) if i not in keep]
    coupling = np.abs(A[np.ix_(keep, dropped)]).max()
    if coupling > 1e-10 * max(np.abs(A).max(), 1.0):
        raise ValueError(f"The lean subsystem is coupled to the dropped states ({coupling:.3g}).")
    return A[np.ix_(keep, keep)]


def lean_eigenvalues(system, spins) -> np.ndarray:
    """Eigenvalues of the lean-heading subsystem for each spin rate, shape (len(spins), 3),
    sorted by real part then imaginary part."""
    out = []
    for s in np.atleast_1d(np.asarray(spins, dtype=np.float64)):
        ev = np.linalg.eigvals(lean_matrix(system, s))
        out.append(ev[np.lexsort((ev.imag, ev.real))])
    return np.array(out)


def _stiffness(system, spin: float) -> float:
    """Sum of the 2x2 principal minors of the lean matrix: the product of its two
    non-trivial eigenvalues (its third is 0, the heading-rate integral). Negative: a real
    pair, one growing (falls); positive: an imaginary pair (wobbles, self-stable)."""
    A = lean_matrix(system, spin)
    n = len(A)
    return float(
        sum(A[i, i] * A[j, j] - A[i, j] * A[j, i] for i in range(n) for j in range(i + 1, n))
    )


def critical_spin(system, xtol: float = 1e-14) -> float:
    """The spin rate |psi'| (rad/s) above which upright rolling has no growing mode, found
    as the sign change of the lean stiffness computed from the exact linearisation."""
    if _stiffness(system, 0.0) >= 0:
        raise ValueError("Upright disk at rest is not unstable: check the model parameters.")
    hi = 1.0
    while _stiffness(system, hi) <= 0:
        hi *= 2.0
        if hi > 1e6:
            raise RuntimeError("No critical spin rate below 1e6 rad/s.")
    return float(brentq(lambda s: _stiffness(system, s), 0.0, hi, xtol=xtol, rtol=1e-15))


def simulate_lean(
    system,
    spin: float,
    lean_rate0: float = 0.05,
    lean0: float = 0.0,
    duration: float = 10.0,
    dt: float = 0.005,
    fall: float = 1.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Nonlinear RK4 simulation (with constraint projection) of the unforced disk from
    upright rolling at `spin`, disturbed by a lean rate `lean_rate0` rad/s and a lean
    `lean0` rad. Stops once |theta - pi/2| exceeds `fall` rad (lying down, where the Euler
    angles degenerate). Returns times (s) and the lean theta - pi/2 (rad)."""
    i_theta = system.coordinates.index("theta")
    x = upright_rolling(system, spin)
    x[i_theta] += lean0
    x[system.n_q + i_theta] += lean_rate0
    x = system.project(x)
    steps = int(round(duration / dt))
    times, lean = [0.0], [x[i_theta] - np.pi / 2]
    for k in range(steps):
        x = system.step(x, None, dt)
        times.append((k + 1) * dt)
        lean.append(x[i_theta] - np.pi / 2)
        if abs(lean[-1]) > fall:
            break
    return np.array(times), np.array(lean)


def linear_lean(system, spin: float, lean_rate0: float, times) -> np.ndarray:
    """The lean predicted by the linearisation after a lean-rate kick `lean_rate0` from
    upright rolling (the heading-rate integral stays 0): lean_rate0 * sinh(s t) / s with
    s^2 = -stiffness (sin(w t) / w above the critical spin)."""
    k = -_stiffness(system, spin)  # s^2: > 0 below the critical spin
    s = np.sqrt(complex(k))
    times = np.asarray(times, dtype=np.float64)
    if s == 0:
        return lean_rate0 * times
    return (lean_rate0 * np.sinh(s * times) / s).real


def plot(system, path: str, margin: float = 0.05) -> None:
    """Eigenvalues against spin rate, and nonlinear lean histories just below and just
    above the critical spin rate (factors 1 -+ margin), saved to `path`."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    wc = critical_spin(system)
    r = system.parameters["r"]
    spins = np.linspace(0.0, 3.0 * wc, 301)
    ev = lean_eigenvalues(system, spins)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    for k in range(ev.shape[1]):
        ax1.plot(spins, ev[:, k].real, "C0.", ms=2, label="real part" if k == 0 else None)
        ax1.plot(spins, ev[:, k].imag, "C1.", ms=2, label="imaginary part" if k == 0 else None)
    ax1.axvline(
        wc, color="k", ls="--", lw=1, label=f"critical {wc:.4f} rad/s (v = {wc * r:.3f} m/s)"
    )
    ax1.set_xlabel("spin rate |psi'| (rad/s)")
    ax1.set_ylabel("eigenvalue (1/s)")
    ax1.set_title("Upright rolling disk: lean-heading eigenvalues")
    ax1.legend(fontsize=8)
    for factor, color in ((1 - margin, "C3"), (1 + margin, "C2")):
        t, lean = simulate_lean(system, factor * wc, KICK)
        ax2.plot(t, np.degrees(lean), color, label=f"{factor:.2f} x critical, nonlinear")
        linear = linear_lean(system, factor * wc, KICK, t)
        keep = np.abs(linear) <= 1.2 * np.abs(lean).max()
        ax2.plot(t[keep], np.degrees(linear[keep]), color, ls="--", lw=1, label="linearised")
    ax2.set_xlabel("time (s)")
    ax2.set_ylabel("lean theta - 90 deg (deg)")
    ax2.set_title(f"Unforced rolling after a lean-rate kick of {KICK} rad/s")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=120)
    write_atomic(path, buffer.getvalue())
    plt.close(fig)


def report(system, margin: float = 0.05) -> str:
    """Text: critical spin from the linearisation vs the classical formula, and the
    nonlinear outcome just below and above it."""
    p = system.parameters
    wc = critical_spin(system)
    wk = classical_critical_spin(p["m"], p["r"], p["I"], p["J"], p["g"])
    lines = [
        f"rolling disk: m = {p['m']:g} kg, r = {p['r']:g} m, I = {p['I']:g}, J = {p['J']:g} "
        f"kg*m^2, g = {p['g']:g} m/s^2",
        f"critical spin from the linearisation: {wc:.12f} rad/s (speed {wc * p['r']:.6f} m/s)",
        f"classical sqrt(m g r I / (J (J + m r^2))): {wk:.12f} rad/s "
        f"(relative difference {abs(wc - wk) / wk:.2e})",
    ]
    if np.isclose(p["I"], p["m"] * p["r"] ** 2 / 4) and np.isclose(p["J"], 2 * p["I"]):
        lines.append(f"thin uniform disk sqrt(g / (3 r)): {np.sqrt(p['g'] / (3 * p['r'])):.12f}")
    lines.append("spin / critical   eigenvalues (1/s)")
    for f in (0.0, 0.5, 0.9, 1.1, 2.0):
        ev = lean_eigenvalues(system, f * wc)[0]
        lines.append(f"  {f:4.1f}   " + "  ".join(f"{e.real:+.4f}{e.imag:+.4f}j" for e in ev))
    for factor in (1 - margin, 1 + margin):
        t, lean = simulate_lean(system, factor * wc, KICK)
        k = -_stiffness(system, factor * wc)
        mode = f"grows at {np.sqrt(k):.4f} 1/s" if k > 0 else f"wobbles at {np.sqrt(-k):.4f} rad/s"
        linear = linear_lean(system, factor * wc, KICK, t)
        small = np.abs(linear) < 0.05
        lines.append(
            f"spin {factor:.2f} x critical, lean-rate kick {KICK} rad/s: linearised lean "
            f"{mode}; nonlinear max |lean| {np.abs(lean).max():.4f} rad over {t[-1]:.1f} s; "
            f"nonlinear - linear while |lean| < 0.05: {np.abs(lean - linear)[small].max():.1e} rad"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m dynamics.disk_stability",
        description="Self-stability of upright rolling: eigenvalues vs spin rate, critical "
        "speed from the exact linearisation vs the classical formula, nonlinear checks.",
    )
    parser.add_argument("--plot", metavar="FILE", help="save the eigenvalue/simulation figure")
    parser.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="override a rolling_disk parameter (m, r, I, J, g); repeatable",
    )
    parser.add_argument(
        "--margin", type=float, default=0.05, help="simulate at (1 -+ margin) x critical"
    )
    args = parser.parse_args(argv)
    import dynamics

    params = {}
    for item in args.param:
        name, sep, value = item.partition("=")
        if not sep:
            parser.error(f"--param expects NAME=VALUE, got {item!r}")
        params[name] = value
    try:
        system = dynamics.get_model("rolling_disk").compile(**params)
    except (TypeError, ValueError) as e:
        parser.error(str(e))
    print(report(system, args.margin))
    if args.plot:
        plot(system, args.plot, args.margin)
        print(f"saved {args.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
