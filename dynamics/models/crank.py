"""The heavy eccentric disk driving a slider through a massless rod (problem 7/3)."""

from __future__ import annotations

import sympy as sp
import sympy.physics.mechanics as me

from ..spec import ModelSpec, Param, generalized_forces, t


def slider_position(theta, R, l, h):
    """x of the slider when the crank pin P is at angle theta (the branch right of P).

    The rod joins P = (R cos theta, R sin theta) to the slider S = (x, -h), so
    (x - R cos theta)^2 + (R sin theta + h)^2 = l^2 and x = R cos theta + sqrt(...).
    """
    return R * sp.cos(theta) + sp.sqrt(l**2 - (R * sp.sin(theta) + h) ** 2)


class slider_x(sp.Function):  # noqa: N801 (a sympy function, named like sin and sqrt)
    """slider_x(n, theta, R, l, h): the n-th derivative d^n x / d theta^n of
    `slider_position`, kept as one symbol-like function while deriving.

    It differentiates by the chain rule (theta raises n), prints as the explicit expression in
    generated code (the `_pythoncode` and `_numpycode` printer hooks) and as x_S^(n)(theta)
    in LaTeX. Left explicit, the square root makes sympy's simplification of the equations
    take minutes; kept whole, about a second.
    """

    def explicit(self) -> sp.Expr:
        n, theta, R, l, h = self.args
        return sp.diff(slider_position(theta, R, l, h), theta, int(n))

    def fdiff(self, argindex=1):
        n, theta, R, l, h = self.args
        if argindex == 2:
            return slider_x(n + 1, theta, R, l, h)
        if argindex == 1:
            raise ValueError("slider_x is not differentiable in its order n.")
        return sp.diff(self.explicit(), self.args[argindex - 1])

    def _pythoncode(self, printer):
        return f"({printer._print(self.explicit())})"  # an atom wherever it lands

    _numpycode = _pythoncode  # the code printers' hooks (scalar math and numpy columns)

    def _latex(self, printer, exp=None):
        n, theta = int(self.args[0]), printer._print(self.args[1])
        primes = "'" * n if n < 4 else f"^{{({n})}}"
        tex = rf"x_S{primes}\left({theta}\right)"
        return tex if exp is None else rf"{tex}^{{{exp}}}"


def eccentric_disk_slider() -> ModelSpec:
    """Problem 7/3: a heavy eccentric disk on a fixed smooth horizontal axle O drives, through
    a massless rod PS of length l, a particle S on a smooth horizontal surface.

    The book gives no figure; the geometry used here (x right, y up, O at the origin)::

                     P (crank pin, OP = R)
                    /  \\
            G      /     \\  rod, length l (massless, pinned at P and S)
              \\  / theta   \\
                O ----------  \\ -------> x      (theta: angle of OP from +x, CCW +)
                |               \\
                | h              S  slider, mass m, moves along x on y = -h
            ==========================================  smooth horizontal surface

    O, G and P lie on one line: G is the disk's mass centre at signed distance s from O
    along OP (s < 0 puts G on the far side of O from P; s = 0 is a balanced disk). The disk
    (mass M, moment of inertia I about O) is the only body gravity does work on: the
    particle moves horizontally. Coordinate: theta alone. The rod is massless and pinned,
    so it only transmits a force along PS, and the slider's position is the holonomic
    function x = R cos(theta) + sqrt(l^2 - (R sin(theta) + h)^2) of theta (the slider stays
    to the right of P), embedded in T. Input tau: motor torque on the disk (ground on disk,
    CCW +), N*m.

    Requires l > R + |h|: then the rod never stands vertical and the disk turns fully.
    Otherwise, where R sin(theta) + h = +-l the rod is vertical, theta reaches an extreme
    and the mechanism locks (the slider cannot be pushed past it, nor the disk turned
    further). With l > R + |h| the dead centres are where the rod lines up with OP
    (d x / d theta = 0; theta = 0 and pi when h = 0): there a force on the slider exerts
    no torque on the disk, so the slider cannot drive the disk through them, while the
    motor can. Outputs: slider_x, slider_v (m, m/s), rod_tension (N, pulling S towards P)
    and normal_force (N, of the surface on the particle; negative would mean it lifts off).
    Points for external forces (`ModelSpec.points`, components along x and y): slider, S
    (the surface takes a vertical force), and pin, P.
    """
    theta = me.dynamicsymbols("theta")
    I, M, m, R, l, g = sp.symbols("I M m R l g", positive=True)
    s, h = sp.symbols("s h", real=True)
    tau = sp.Symbol("tau")

    x = slider_x(0, theta, R, l, h)
    v = x.diff(t)
    T = I * theta.diff(t) ** 2 / 2 + m * v**2 / 2
    V = M * g * s * sp.sin(theta)
    Q = generalized_forces((theta,), [(sp.Matrix([theta.diff(t)]), sp.Matrix([tau]))])

    # the rod force on S is along S->P: m x'' = tension (P_x - x)/l and, vertically,
    # 0 = normal + tension (P_y + h)/l - m g
    a = v.diff(t)
    dx, dy = R * sp.cos(theta) - slider_position(theta, R, l, h), R * sp.sin(theta) + h
    tension = m * a * l / dx
    normal = m * g - tension * dy / l
    return ModelSpec(
        name="eccentric_disk_slider",
        coordinates=(theta,),
        inputs=(tau,),
        kinetic=T,
        potential=V,
        forces=Q,
        outputs={
            "slider_x": x,
            "slider_v": v,
            "rod_tension": tension,
            "normal_force": normal,
        },
        parameters={
            # defaults: a uniform 2 kg disk of radius 0.15 m, I = M (0.15^2 / 2 + s^2)
            I: Param(0.0275, "kg*m^2", "moment of inertia of the disk about its axle O"),
            M: Param(2.0, "kg", "mass of the disk"),
            m: Param(0.5, "kg", "mass of the slider particle"),
            s: Param(0.05, "m", "signed distance OG along OP (< 0: G opposite P)", False),
            R: Param(0.1, "m", "distance OP of the crank pin from the axle"),
            l: Param(0.3, "m", "length of the rod PS (must exceed R + |h|)"),
            h: Param(0.0, "m", "height of O above the slider's line (may be < 0)", False),
            g: Param(9.81, "m/s^2", "gravitational acceleration"),
        },
        conditions={
            "l > R + |h| (else the rod stands vertical and the mechanism locks)": l - R - sp.Abs(h)
        },
        description=eccentric_disk_slider.__doc__,
        points={
            "slider": sp.Matrix([v, 0]),
            "pin": sp.Matrix([R * sp.cos(theta), R * sp.sin(theta)]).diff(t),
        },
    )
