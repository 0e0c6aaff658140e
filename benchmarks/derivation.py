"""Speed of the dynamics layer, with the two-link arm measured against hand-written peers.

    python benchmarks/derivation.py [--quick]
    python benchmarks/derivation.py --scaling [--links 10]

Reports, for every model: cold derive+generate time and first-call (numba) time in a fresh
cache, warm compile time in a fresh process, microseconds per single `state_derivative`
call, and batched throughput at N = 1, 64, 1024, 16384. For the arm, in the same run: a
hand-written closed-form numpy implementation (the limit to approach), and the options for
the single-state path: plain floats + math by hand, sympy-generated scalar code
(lambdify(modules="math") + a Cramer solve), C from sympy's code printer through ctypes,
and the numba kernels this project generates. Ratios are what matter; absolute numbers
depend on the machine. Run with OMP_NUM_THREADS=1.

--scaling: an n-link pendulum on a cart (uniform rods, absolute angles, a force on the cart)
written with the public `ModelSpec` API, n = 1..10, each size in fresh processes with a cold
cache: derive, generate, compile (write and load the module) and first step (numba), the
operations in the generated code, evaluations/s at 1024 rows, beside sympy's `LagrangesMethod`
(mass matrix and forcing) and `KanesMethod` on the same system, each in its own process.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import timeit
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

import dynamics
from dynamics.integrate import DEFAULT_DT

P = dict(m1=1.0, m2=1.0, l=1.0, l1=0.5, l2=0.5, Ibar1=1 / 12, Ibar2=1 / 12, g=9.81)


def per_call(fn, repeat=5, number=2000) -> float:
    """Median seconds per call."""
    fn()
    return float(np.median(timeit.repeat(fn, repeat=repeat, number=number)) / number)


# ---- hand-written arm (eq. 7.25 with Q1 = M1 - M2) ------------------------------------------
IP = P["Ibar1"] + P["m1"] * P["l1"] ** 2 + P["m2"] * P["l"] ** 2
I2 = P["Ibar2"] + P["m2"] * P["l2"] ** 2
A_ = P["m2"] * P["l"] * P["l2"]
B_ = (P["m1"] * P["l1"] + P["m2"] * P["l"]) * P["g"]
C_ = P["m2"] * P["l2"] * P["g"]


def arm_numpy(x, u):
    """Closed form, numpy, any leading shape: Cramer's rule on the 2x2 mass matrix."""
    th1, th2, w1, w2 = x[..., 0], x[..., 1], x[..., 2], x[..., 3]
    c, s = np.cos(th2 - th1), np.sin(th2 - th1)
    m12 = A_ * c
    f1 = u[..., 0] - u[..., 1] + A_ * s * w2**2 - B_ * np.sin(th1)
    f2 = u[..., 1] - A_ * s * w1**2 - C_ * np.sin(th2)
    det = IP * I2 - m12 * m12
    out = np.empty_like(x)
    out[..., 0], out[..., 1] = w1, w2
    out[..., 2] = (I2 * f1 - m12 * f2) / det
    out[..., 3] = (IP * f2 - m12 * f1) / det
    return out


def arm_floats(x, u):
    th1, th2, w1, w2 = x
    c, s = math.cos(th2 - th1), math.sin(th2 - th1)
    m12 = A_ * c
    f1 = u[0] - u[1] + A_ * s * w2 * w2 - B_ * math.sin(th1)
    f2 = u[1] - A_ * s * w1 * w1 - C_ * math.sin(th2)
    det = IP * I2 - m12 * m12
    return (w1, w2, (I2 * f1 - m12 * f2) / det, (IP * f2 - m12 * f1) / det)


def generated_scalar(model):
    """sympy's scalar Python code for M and F, solved by Cramer's rule in floats."""
    import sympy as sp

    code = model.derived.code
    M, F = code.mass, code.forcing
    f = sp.lambdify(
        [code.x, code.u, code.p], [M[0, 0], M[0, 1], M[1, 1], F[0], F[1]], modules="math", cse=True
    )
    p = list(model.parameters.values())

    def rhs(x, u):
        a, b, d_, f1, f2 = f(x, u, p)
        det = a * d_ - b * b
        return (x[2], x[3], (d_ * f1 - b * f2) / det, (a * f2 - b * f1) / det)

    return rhs


def c_arm(model):
    """C from sympy's C printer (cse'd M, F and a Cramer solve), compiled with cc, via ctypes."""
    import sympy as sp

    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        return None
    code = model.derived.code
    M, F = code.mass, code.forcing
    repl, red = sp.cse([M[0, 0], M[0, 1], M[1, 1], F[0], F[1]])
    body = ["void rhs(const double *x, const double *u, const double *p, double *out) {"]
    body += [f"  double q{i} = x[{i}], qd{i} = x[{i + 2}];" for i in range(2)]
    body += [f"  double u{j} = u[{j}];" for j in range(2)]
    body += [f"  double p{k} = p[{k}];" for k in range(len(code.p))]
    body += [f"  double {s} = {sp.ccode(e)};" for s, e in repl]
    body += [f"  double e{i} = {sp.ccode(e)};" for i, e in enumerate(red)]
    body += [
        "  double det = e0 * e2 - e1 * e1;",
        "  out[0] = qd0; out[1] = qd1;",
        "  out[2] = (e2 * e3 - e1 * e4) / det; out[3] = (e0 * e4 - e1 * e3) / det;",
        "}",
    ]
    tmp = Path(tempfile.mkdtemp())
    (tmp / "arm.c").write_text("#include <math.h>\n" + "\n".join(body))
    subprocess.run(
        [cc, "-O2", "-shared", "-fPIC", "-o", str(tmp / "arm.so"), str(tmp / "arm.c"), "-lm"],
        check=True,
    )
    lib = ctypes.CDLL(str(tmp / "arm.so"))
    dp = ctypes.POINTER(ctypes.c_double)
    lib.rhs.argtypes = [dp, dp, dp, dp]
    p = np.array(list(model.parameters.values()))
    out = np.empty(4)
    pp, po = p.ctypes.data_as(dp), out.ctypes.data_as(dp)

    def rhs(x, u):
        lib.rhs(x.ctypes.data_as(dp), u.ctypes.data_as(dp), pp, po)
        return out

    return rhs


# ---- cold and warm timings in fresh processes ------------------------------------------------
COLD = """
import time, json, numpy as np
import dynamics
t0 = time.perf_counter()
m = dynamics.get_model({name!r})
s = m.compile()
t1 = time.perf_counter()
x = np.zeros(s.state_size); x[:s.n_q] = 0.1
if s.n_c: x = s.project(x)
s.state_derivative(0.0, x, np.zeros(s.n_u)); s.step(x, np.zeros(s.n_u), 0.01, 1)
t2 = time.perf_counter()
print(json.dumps([t1 - t0, t2 - t1]))
"""
NUMBA_INIT = """
import time, json
from numba import njit
t0 = time.perf_counter()
njit(lambda a: a + 1)(1.0)
print(json.dumps([time.perf_counter() - t0]))
"""


def in_fresh_process(code: str, cache: str) -> list[float]:
    env = dict(os.environ, LAGRANGE_GYM_CACHE=cache, OMP_NUM_THREADS="1", PYTHONPATH=str(ROOT))
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=600
    )
    if out.returncode != 0:
        raise RuntimeError(out.stderr[-400:])
    return json.loads(out.stdout.strip().splitlines()[-1])


def model_table(names, quick: bool) -> list[str]:
    init = in_fresh_process(NUMBA_INIT, tempfile.mkdtemp())[0]
    rows = [
        f"Fresh processes; the first numba call of any process costs ~{1e3 * init:.0f} ms of "
        "LLVM start-up, included in the first-call columns.",
        "",
        "| model | n, n_c | cold derive+generate s | cold first calls (numba) s | warm compile "
        "ms | warm first calls ms | single call us | N=1 | N=64 | N=1024 | N=16384 |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name in names:
        cache = tempfile.mkdtemp(prefix="lg-bench-")
        try:
            cold = in_fresh_process(COLD.format(name=name), cache)
            warm = in_fresh_process(COLD.format(name=name), cache)
        except RuntimeError as exc:
            rows.append(f"| {name} | failed: {str(exc).splitlines()[-1]} |")
            continue
        s = dynamics.get_model(name).compile()
        rng = np.random.default_rng(0)
        rates = []
        for N in (1, 64, 1024, 16384):
            x = rng.normal(size=(N, s.state_size)) * 0.3
            if name == "rolling_disk":
                x[:, 2] += np.pi / 2
            u = np.zeros((N, s.n_u))
            sec = per_call(
                lambda x=x, u=u: s.state_derivative(0.0, x, u),
                number=max(3, 20000 // N) if not quick else 3,
            )
            rates.append(N / sec)
        x1 = np.zeros(s.state_size) + 0.1
        if name == "rolling_disk":
            x1[2] = np.pi / 2
        single = per_call(lambda: s.state_derivative(0.0, x1, np.zeros(s.n_u)))
        rows.append(
            f"| {name} | {s.n_q}, {s.n_c} | {cold[0]:.2f} | {cold[1]:.2f} | {1e3 * warm[0]:.0f} "
            f"| {1e3 * warm[1]:.0f} | {1e6 * single:.1f} | "
            + " | ".join(f"{r / 1e6:.3g} M/s" for r in rates)
            + " |"
        )
        shutil.rmtree(cache, ignore_errors=True)
    return rows


def arm_table() -> list[str]:
    model = dynamics.get_model("two_link_arm")
    s = model.compile()
    x = np.array([0.3, -0.4, 0.5, 0.2])
    u = np.array([0.1, -0.2])
    ref = arm_numpy(x, u)
    options = {
        "hand-written numpy (closed form)": lambda: arm_numpy(x, u),
        "hand-written floats + math": lambda: arm_floats(x, u),
        "sympy scalar code (lambdify math) + Cramer": (lambda f=generated_scalar(model): f(x, u)),
    }
    crhs = c_arm(model)
    if crhs is not None:
        options["C from sympy's ccode, via ctypes"] = lambda: crhs(x, u)
    T1, X1, U1, out1 = np.zeros(1), x[None].copy(), u[None].copy(), np.empty((1, 4))
    options["numba kernel (ours), raw"] = lambda: (
        s._m.derivative_batch(T1, X1, U1, s._p, out1),
        out1,
    )[1]
    options["System.state_derivative (ours, checked)"] = lambda: s.state_derivative(0.0, x, u)
    rows = [
        "| single-state path, two-link arm | us per call | vs hand-written numpy |",
        "|---|---|---|",
    ]
    base = per_call(options["hand-written numpy (closed form)"])
    for label, fn in options.items():
        np.testing.assert_allclose(np.asarray(fn(), dtype=float).ravel()[-4:], ref, rtol=1e-12)
        sec = per_call(fn)
        rows.append(f"| {label} | {1e6 * sec:.2f} | {sec / base:.2f}x |")

    rows += [
        "",
        "| batched, two-link arm | ours M states/s | hand-written numpy M states/s | "
        "ours / hand-written |",
        "|---|---|---|---|",
    ]
    rng = np.random.default_rng(1)
    for N in (1, 64, 1024, 16384):
        xb, ub = rng.normal(size=(N, 4)), rng.normal(size=(N, 2))
        np.testing.assert_allclose(
            s.state_derivative(0.0, xb, ub), arm_numpy(xb, ub), rtol=1e-10, atol=1e-10
        )
        number = max(3, 20000 // N)
        ours = per_call(lambda xb=xb, ub=ub: s.state_derivative(0.0, xb, ub), number=number)
        hand = per_call(lambda xb=xb, ub=ub: arm_numpy(xb, ub), number=number)
        rows.append(
            f"| N = {N} | {N / ours / 1e6:.3g} | {N / hand / 1e6:.3g} | {hand / ours:.2f}x |"
        )
    return rows


def step_table() -> list[str]:
    """Cost of integration at the default accuracy (RK4, h = DEFAULT_DT)."""
    rows = [
        f"| RK4 at h = {DEFAULT_DT:g} s (energy drift <= 1e-6 per 10 s) | us per substep, "
        "one state | us per 0.05 s env step (50 substeps), one state | "
        "M state-substeps/s at N = 1024 |",
        "|---|---|---|---|",
    ]
    for name in ("two_link_arm", "rolling_disk", "bead_on_driven_rod"):
        s = dynamics.get_model(name).compile()
        x = np.zeros(s.state_size) + 0.1
        if name == "rolling_disk":
            x[2] = np.pi / 2
            x = s.project(x)
        T, X, U, out = np.zeros(1), x[None].copy(), np.zeros((1, s.n_u)), np.empty((1, len(x)))
        one = per_call(lambda: s.step_unchecked(T, X, U, DEFAULT_DT, 1, out))
        env = per_call(lambda: s.step_unchecked(T, X, U, 0.05, 50, out), number=500)
        N = 1024
        TN, XN, UN = np.zeros(N), np.repeat(X, N, 0), np.zeros((N, s.n_u))
        outN = np.empty_like(XN)
        batch = per_call(lambda: s.step_unchecked(TN, XN, UN, 0.01, 10, outN), number=5)
        rows.append(f"| {name} | {1e6 * one:.2f} | {1e6 * env:.1f} | {N * 10 / batch / 1e6:.2f} |")
    return rows


# ---- scaling: an n-link pendulum on a cart ---------------------------------------------------
CHAIN = dict(m_c=1.0, m=0.3, l=0.5, g=9.81)


def cart_chain(n: int):
    """n uniform rods of mass m and length l in series on a cart of mass m_c, absolute angles
    theta_i from upright, force F on the cart: T, V and Q by hand (the book's recipe)."""
    import sympy as sp
    import sympy.physics.mechanics as me

    from dynamics.spec import ModelSpec, Param, t

    x = me.dynamicsymbols("x")
    th = me.dynamicsymbols(f"theta1:{n + 1}")
    mc, m, l, g = sp.symbols("m_c m l g", positive=True)
    F = sp.Symbol("F")
    T, V = mc * x.diff(t) ** 2 / 2, sp.S.Zero
    px, py = x, sp.S.Zero
    for i in range(n):
        cx, cy = px + l / 2 * sp.sin(th[i]), py + l / 2 * sp.cos(th[i])
        T += m * (cx.diff(t) ** 2 + cy.diff(t) ** 2) / 2 + m * l**2 / 24 * th[i].diff(t) ** 2
        V += m * g * cy
        px, py = px + l * sp.sin(th[i]), py + l * sp.cos(th[i])
    units = {mc: "kg", m: "kg", l: "m", g: "m/s^2"}
    params = {s: Param(CHAIN[str(s)], units[s]) for s in (mc, m, l, g)}
    return ModelSpec(f"cart_chain_{n}", (x, *th), T, V, params, (F,), {x: F})


def sympy_chain(n: int, method: str):
    """The same system through sympy.physics.mechanics as its users write it: a particle and
    rigid bodies in frames, gravity and F as loads, then `LagrangesMethod` on their
    Lagrangian or `KanesMethod` (u = qdot). Returns (seconds, coordinates, rates, M, F) of
    M [qddot] = F (Kane: M [udot] = F)."""
    import time

    import sympy as sp
    import sympy.physics.mechanics as me

    t0 = time.perf_counter()
    mc, m, l, g = sp.symbols("m_c m l g", positive=True)
    F = sp.Symbol("F")
    q = me.dynamicsymbols(f"q0:{n + 1}")
    u = me.dynamicsymbols(f"u0:{n + 1}")
    rates = [qi.diff() for qi in q] if method == "lagrange" else u
    N = me.ReferenceFrame("N")  # x right, y up
    O = me.Point("O")
    O.set_vel(N, 0)
    cart = O.locatenew("C", q[0] * N.x)
    cart.set_vel(N, rates[0] * N.x)
    bodies = [me.Particle("cart", cart, mc)]
    loads = [(cart, F * N.x)]
    joint = cart
    for i in range(n):
        # theta from upright, tipping towards +x: the rod's axis is sin(th) x + cos(th) y
        A = N.orientnew(f"A{i}", "Axis", (q[i + 1], -N.z))
        A.set_ang_vel(N, -rates[i + 1] * N.z)
        G = joint.locatenew(f"G{i}", l / 2 * A.y)
        G.v2pt_theory(joint, N, A)
        inertia = me.inertia(A, 0, 0, m * l**2 / 12)
        bodies.append(me.RigidBody(f"rod{i}", G, A, m, (inertia, G)))
        loads.append((G, -m * g * N.y))
        joint = joint.locatenew(f"J{i}", l * A.y)
        joint.v2pt_theory(G, N, A)
    if method == "lagrange":
        lm = me.LagrangesMethod(me.Lagrangian(N, *bodies), q, forcelist=loads, frame=N)
        lm.form_lagranges_equations()
        M, Fv = lm.mass_matrix, lm.forcing
    else:
        kd = [qi.diff() - ui for qi, ui in zip(q, u)]
        km = me.KanesMethod(N, q_ind=q, u_ind=u, kd_eqs=kd)
        km.kanes_equations(bodies, loads)
        M, Fv = km.mass_matrix, km.forcing
    return time.perf_counter() - t0, q, rates, M, Fv


def scaling_one(n: int, what: str) -> dict:
    """One size, in this (fresh) process: times in seconds, sizes, evaluations/s."""
    import time

    import sympy as sp
    import sympy.physics.mechanics  # noqa: F401  (imports are not derivation time)

    import dynamics.codegen
    import dynamics.derive

    # a size-1 derivation first, untimed, so that no method pays sympy's first-use costs
    if what == "ours":
        dynamics.codegen.generate(dynamics.derive.derive(cart_chain(1)), "warm-up")
    else:
        sympy_chain(1, what)
    if what != "ours":
        seconds, q, rates, M, F = sympy_chain(n, what)
        out = {"seconds": seconds, "ops": int(sp.count_ops(list(M) + list(F)))}
        if what == "lagrange":  # the same equations as ours, checked at one state
            from dynamics.derive import derive

            code = derive(cart_chain(n)).code
            rng = np.random.default_rng(n)
            xv = rng.uniform(-2, 2, 2 * (n + 1))
            pv = [CHAIN[k] for k in ("m_c", "m", "l", "g")]
            mc, m, l, g = sp.symbols("m_c m l g", positive=True)
            point = dict(zip([r.diff() for r in rates], [0.0] * (n + 1)))
            point |= dict(zip(rates, xv[n + 1 :])) | dict(zip(q, xv[: n + 1]))
            point |= dict(zip((mc, m, l, g), pv)) | {sp.Symbol("F"): 0.7}
            theirs = [float(me_subs(e, point)) for e in [*M, *F]]
            values = dict(zip(code.x, xv)) | dict(zip(code.p, pv)) | {code.u[0]: 0.7}
            ours = [float(e.xreplace(values)) for e in [*code.mass, *code.forcing]]
            np.testing.assert_allclose(ours, theirs, rtol=1e-9, atol=1e-9)
        return out

    from dynamics import cache
    from dynamics.codegen import generate
    from dynamics.program import Program
    from dynamics.system import System

    model = dynamics.Model(cart_chain(n))
    t0 = time.perf_counter()
    d = model.derived
    t1 = time.perf_counter()
    source = generate(d, model.key)
    t2 = time.perf_counter()
    system = System(cache.load_or_build(model.name, model.key, lambda: source))
    t3 = time.perf_counter()
    x = np.zeros(system.state_size)
    x[1 : n + 1] = 0.1
    system.step(x, [0.0], 0.01)
    t4 = time.perf_counter()
    code = d.code
    prog = Program({"m": list(code.mass), "f": list(code.forcing)})
    steps = prog.needed(prog.results["m"] + prog.results["f"])
    rng = np.random.default_rng(0)
    X = rng.normal(size=(1024, system.state_size)) * 0.5
    U = rng.normal(size=(1024, 1))
    sec = per_call(lambda: system.state_derivative(0.0, X, U), number=20)
    return {
        "derive": t1 - t0,
        "generate": t2 - t1,
        "compile": t3 - t2,
        "first_step": t4 - t3,
        "ops": int(sp.count_ops(list(code.mass) + list(code.forcing))),
        "ops_cse": int(sp.count_ops([e for _, e in steps] + prog.results["m"] + prog.results["f"])),
        "evals": 1024 / sec,
    }


def me_subs(expr, point):
    import sympy.physics.mechanics as me

    return me.msubs(expr, point)


def scaling_table(links: int) -> list[str]:
    rows = [
        "One process per size and method, cold cache. ours = derive + generate + compile "
        "(write and load the module); first step = numba's compilation of the integrator; "
        "LM = sympy `LagrangesMethod` (bodies, Lagrangian, M and F); Kane = `KanesMethod`. "
        "Operations: sympy `count_ops` of M and F (ours as generated, then after the shared "
        "common-subexpression pass that the kernels print).",
        "",
        "| n | coords | derive s | generate s | compile s | ours s | first step s | LM s | Kane s "
        "| ours / LM | ops ours M,F | ops after CSE | ops LM M,F | evaluations/s, 1024 rows |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for n in range(1, links + 1):
        got = {}
        for what in ("ours", "lagrange", "kane"):
            cache = tempfile.mkdtemp(prefix="lg-scaling-")
            env = dict(os.environ, LAGRANGE_GYM_CACHE=cache, OMP_NUM_THREADS="1")
            out = subprocess.run(
                [sys.executable, __file__, "--scaling-one", str(n), what],
                capture_output=True,
                text=True,
                env=env,
                timeout=1800,
            )
            shutil.rmtree(cache, ignore_errors=True)
            if out.returncode != 0:
                raise RuntimeError(f"n = {n}, {what}: {out.stderr[-600:]}")
            got[what] = json.loads(out.stdout.strip().splitlines()[-1])
        o, lm, kane = got["ours"], got["lagrange"], got["kane"]
        ours = o["derive"] + o["generate"] + o["compile"]
        rows.append(
            f"| {n} | {n + 1} | {o['derive']:.2f} | {o['generate']:.2f} | {o['compile']:.2f} "
            f"| {ours:.2f} | {o['first_step']:.1f} | {lm['seconds']:.2f} | {kane['seconds']:.2f} "
            f"| {ours / lm['seconds']:.2f}x | {o['ops']} | {o['ops_cse']} | {lm['ops']} "
            f"| {o['evals']:.3g} |"
        )
        print(rows[-1], file=sys.stderr, flush=True)
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer repetitions")
    parser.add_argument("--models", nargs="*", default=None, help="models to time (default all)")
    parser.add_argument("--scaling", action="store_true", help="n-link chain on a cart, n = 1..")
    parser.add_argument("--links", type=int, default=10, help="largest n for --scaling")
    parser.add_argument("--scaling-one", nargs=2, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.scaling_one:
        print(json.dumps(scaling_one(int(args.scaling_one[0]), args.scaling_one[1])))
        return 0
    if args.scaling:
        print("\n".join(scaling_table(args.links)))
        return 0
    names = args.models or dynamics.list_models()
    print("\n".join(arm_table()))
    print()
    print("\n".join(step_table()))
    print()
    print("\n".join(model_table(names, args.quick)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
