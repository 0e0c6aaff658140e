"""How a model is declared: the four steps of section 7.1 written as data.

A `ModelSpec` holds what a textbook asks for: generalised coordinates, kinetic and potential
energy, non-conservative generalised forces (inputs appear in them as plain symbols),
nonholonomic (Pfaffian) constraints, coordinates whose motion is prescribed in time
(rheonomic driving), and parameters with SI defaults. Nothing here derives anything.
"""

from __future__ import annotations

import numbers
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me

from .calculus import compact

t = me.dynamicsymbols._t
"""The time symbol of every model (the one `dynamicsymbols` differentiate by)."""


@dataclass(frozen=True)
class Param:
    """A model parameter: SI default, unit, meaning; `positive` ones must be > 0,
    `nonnegative` ones (with positive=False) >= 0 (a friction coefficient, a damping)."""

    default: float
    unit: str
    doc: str = ""
    positive: bool = True
    nonnegative: bool = field(default=False, repr=False)

    def __post_init__(self):
        d = self.default
        real = isinstance(d, (int, float, np.integer, np.floating))
        if isinstance(d, (bool, np.bool_)) or not real:
            raise TypeError(f"Param.default must be a real number, got {d!r}.")
        if not np.isfinite(d):
            raise ValueError(f"Param.default must be finite, got {d!r}.")
        for flag in ("positive", "nonnegative"):
            if not isinstance(getattr(self, flag), (bool, np.bool_)):
                raise TypeError(f"Param.{flag} must be True or False, got {getattr(self, flag)!r}.")


@dataclass(frozen=True)
class ModelSpec:
    """A mechanical system as chapter 7 formulates it.

    coordinates: generalised coordinates (dynamicsymbols), in the order of the state.
    kinetic, potential: T and V in the coordinates, their rates, parameters and time `t`.
    forces: non-conservative generalised forces Q_s by coordinate (see `generalized_forces`).
    inputs: plain symbols (torques, forces) that appear in `forces`.
    parameters: symbol -> Param.
    constraints: Pfaffian constraints sum_s B_rs qdot_s + b_r = 0, each an expression that
        must vanish, linear in the coordinate rates (eq. 7.36 adds lambda_r B_rs).
    prescribed: coordinates whose motion is given as a function of `t` (rheonomic driving);
        T, V and forces may use them, and the generalised force that keeps them on their
        schedule is reported as an output named `reaction_<name>`.
    outputs: further named expressions of q, qdot, qddot, t, inputs (reported by the system).
    conditions: {statement: expression in the parameters that must be > 0}, checked when
        the model is compiled with numbers (e.g. {"l > R + |h|": l - R - Abs(h)}).
    bodies: {name: inertia}, the rigid bodies whose inertia the parameters give: the three
        principal moments (a tuple, e.g. (I, I, J) for a disk) or the symmetric 3x3 tensor
        (a Matrix or nested tuples, entries expressions in the parameters, 0 allowed) about
        any point. Every set of parameter values is then checked to give each body an
        inertia some mass distribution has (positive definite, each principal moment at most
        the sum of the other two), and randomisation draws such a body as a whole.
    points: {name: velocity}, points an external force may act on (the envs' pushes): the
        velocity of each as a column Matrix of 2 or 3 components in any basis (a force is
        given by its components in the same basis); a force f there has the generalised
        forces f . dv/dqdot_s (`generalized_forces`). The first is the default point.
    """

    name: str
    coordinates: tuple
    kinetic: sp.Expr
    potential: sp.Expr
    parameters: Mapping
    inputs: tuple = ()
    forces: Mapping = field(default_factory=dict)
    constraints: tuple = ()
    prescribed: Mapping = field(default_factory=dict)
    outputs: Mapping = field(default_factory=dict)
    conditions: Mapping = field(default_factory=dict)
    description: str = ""
    points: Mapping = field(default_factory=dict)
    bodies: Mapping = field(default_factory=dict)

    def __post_init__(self):
        coords = set(self.coordinates) | set(self.prescribed)
        for q in self.forces:
            if q not in coords:
                raise ValueError(f"{self.name}: force given for {q}, which is not a coordinate.")
        if len(set(self.coordinates)) != len(self.coordinates):
            raise ValueError(f"{self.name}: repeated coordinate in {self.coordinates}.")
        names = [str(s) for s in self.parameters] + [str(s) for s in self.inputs]
        if len(set(names)) != len(names):
            raise ValueError(f"{self.name}: parameter and input names must be unique: {names}.")
        self._refuse_text()
        for q in (*self.coordinates, *self.prescribed):
            if getattr(q, "args", None) != (t,):
                raise ValueError(
                    f"{self.name}: coordinate {q} is not a function of dynamics.spec.t "
                    "(make coordinates with sympy.physics.mechanics.dynamicsymbols)."
                )
        for label, value in self._expressions():
            foreign = [s for s in sp.sympify(value).free_symbols if s.name == t.name and s != t]
            if foreign:
                raise ValueError(
                    f"{self.name}: {label} uses a time symbol {foreign[0]!r} with other "
                    "assumptions than dynamics.spec.t, the time the derivation differentiates "
                    "by; its terms would be constants. Use `from dynamics.spec import t`."
                )
        for name, v in self.points.items():
            if not (isinstance(name, str) and name.isidentifier()):
                raise ValueError(f"{self.name}: point name {name!r} is not an identifier.")
            if not (isinstance(v, sp.MatrixBase) and v.shape in ((2, 1), (3, 1))):
                raise ValueError(
                    f"{self.name}: points[{name!r}] must be the point's velocity as a column "
                    f"Matrix of 2 or 3 components, got {v!r:.80}."
                )

        self._check_symbols()
        self._check_bodies()

    def _refuse_text(self) -> None:
        """No field sympy would parse holds text (sympify evals it: never pass text on), and
        every expression is a sympy object or a number (a list is no energy)."""
        for label, value in self._sympy_fields():
            text = _first_text(value)
            if text is not None:
                raise TypeError(
                    f"{self.name}: {label} is text {text!r:.80}; give a sympy expression "
                    "(dynamics.parse.parse_expression reads text without running code)."
                )
        for label, value in self._expressions():
            if not isinstance(value, (sp.Basic, sp.MatrixBase, numbers.Real)) or isinstance(
                value, bool
            ):
                raise TypeError(
                    f"{self.name}: {label} must be a sympy expression (or a number), got "
                    f"{type(value).__name__} {value!r:.80}."
                )

    def _sympy_fields(self):
        """Every field whose entries sympy could parse: the expressions, the symbols, the
        bodies' moments (names, units and statements are text by design)."""
        yield from self._expressions()
        yield "coordinates", tuple(self.coordinates)
        yield "inputs", tuple(self.inputs)
        yield "parameters (its keys)", tuple(self.parameters)
        yield "forces (its keys)", tuple(self.forces)
        yield "prescribed (its keys)", tuple(self.prescribed)
        yield from ((f"bodies[{k!r}]", v) for k, v in self.bodies.items())

    def _check_symbols(self) -> None:
        """Every symbol in T, V, Q, the constraints, outputs, conditions and points is a
        declared parameter or input (or the time t): an undeclared one would surface only
        in the compiler's words."""
        declared = set(self.parameters) | set(self.inputs) | {t}
        for label, value in self._expressions():
            extra = sorted(str(s) for s in sp.sympify(value).free_symbols - declared)
            if extra:
                raise ValueError(
                    f"{self.name}: {label} uses {', '.join(extra)}, declared neither as a "
                    f"parameter nor as an input (add it to `parameters` with a Param)."
                )
        for k, p in self.parameters.items():
            if not isinstance(p, Param):
                raise TypeError(
                    f"{self.name}: parameters[{k}] must be a Param(default, unit), got {p!r:.80}."
                )

    def _check_bodies(self) -> None:
        params = set(self.parameters)
        for name, inertia in self.bodies.items():
            try:
                matrix = inertia_matrix(inertia)
            except (TypeError, ValueError, sp.SympifyError):
                matrix = None
            if matrix is None or matrix != matrix.T:
                raise ValueError(
                    f"{self.name}: bodies[{name!r}] must be 3 principal moments or a symmetric "
                    f"3x3 inertia tensor, got {inertia!r:.80}."
                )
            foreign = sorted(str(s) for s in matrix.free_symbols - params)
            if foreign:
                raise ValueError(
                    f"{self.name}: bodies[{name!r}] uses {foreign}, which are not parameters."
                )

    def _expressions(self):
        yield "kinetic", self.kinetic
        yield "potential", self.potential
        yield from ((f"forces[{k}]", v) for k, v in self.forces.items())
        yield from ((f"constraints[{i}]", v) for i, v in enumerate(self.constraints))
        yield from ((f"prescribed[{k}]", v) for k, v in self.prescribed.items())
        yield from ((f"outputs[{k!r}]", v) for k, v in self.outputs.items())
        yield from ((f"conditions[{k!r}]", v) for k, v in self.conditions.items())
        yield from ((f"points[{k!r}]", v) for k, v in self.points.items())

    def fingerprint(self) -> str:
        """A canonical text of everything that determines the derived equations."""
        parts = [
            self.name,
            sp.srepr(tuple(self.coordinates)),
            sp.srepr(self.kinetic),
            sp.srepr(self.potential),
            sp.srepr(tuple(self.inputs)),
            sp.srepr(sorted(((sp.srepr(k), sp.srepr(v)) for k, v in self.forces.items()))),
            sp.srepr(tuple(self.constraints)),
            sp.srepr(sorted(((sp.srepr(k), sp.srepr(v)) for k, v in self.prescribed.items()))),
            sp.srepr(sorted(((k, sp.srepr(v)) for k, v in self.outputs.items()))),
            repr(sorted((str(k), v) for k, v in self.parameters.items())),
            sp.srepr(sorted(((k, sp.srepr(v)) for k, v in self.conditions.items()))),
        ]
        if self.points:  # (a spec without points keeps its former fingerprint)
            parts.append(sp.srepr([(k, sp.srepr(v)) for k, v in self.points.items()]))
        if self.bodies:  # (likewise for bodies and non-negative parameters)
            bodies = [(k, sp.srepr(inertia_matrix(v))) for k, v in self.bodies.items()]
            parts.append(sp.srepr(bodies))
        nonnegative = sorted(str(k) for k, p in self.parameters.items() if p.nonnegative)
        if nonnegative:
            parts.append(f"nonnegative {nonnegative}")
        return "\n".join(parts)


def _first_text(value):
    """The first str or bytes in `value` (nested tuples, lists, dicts, matrices), else None."""
    if isinstance(value, (str, bytes)):
        return value
    if isinstance(value, Mapping):
        value = [*value.keys(), *value.values()]
    if isinstance(value, (tuple, list, sp.MatrixBase)):
        return next((x for x in map(_first_text, value) if x is not None), None)
    return None


def inertia_matrix(inertia) -> sp.Matrix:
    """A body's declared inertia (3 principal moments, or a 3x3 tensor) as a 3x3 Matrix."""
    if isinstance(inertia, sp.MatrixBase):
        m = sp.Matrix(inertia)
    elif len(inertia) == 3 and all(not isinstance(v, (tuple, list)) for v in inertia):
        m = sp.diag(*[sp.sympify(v) for v in inertia])
    else:
        m = sp.Matrix([[sp.sympify(v) for v in row] for row in inertia])
    if m.shape != (3, 3):
        raise ValueError(f"an inertia is 3x3, got shape {m.shape}")
    return m


def generalized_forces(
    coordinates: Sequence, applied: Iterable, frame: me.ReferenceFrame | None = None
) -> dict:
    """Generalised forces of given forces and torques by virtual work (eq. 6.15).

    Q_s = sum_i F_i . d(v_i)/d(qdot_s): each entry of `applied` is a pair (velocity, force),
    the velocity of the point the force acts on (or the angular velocity of the body a torque
    acts on) and the force (or torque). Both may be sympy.physics.vector Vectors in `frame`,
    or column Matrices of Cartesian components (e.g. the time derivative of a position given
    by transformation equations). Returns {coordinate: Q_s}, each expanded where that makes
    it smaller (no general simplification: it costs seconds per entry for a large system).
    """
    coordinates = list(coordinates)
    rates = [q.diff(t) for q in coordinates]
    Q = {q: sp.S.Zero for q in coordinates}
    for velocity, force in applied:
        if isinstance(velocity, me.Vector):
            if frame is None:
                raise ValueError("generalized_forces needs `frame` for Vector arguments.")
            partials = me.partial_velocity([velocity], rates, frame)[0]
            for q, vq in zip(coordinates, partials):
                Q[q] += vq.dot(force)
        else:
            v = sp.Matrix(velocity)
            f = sp.Matrix(force)
            if v.shape != f.shape:
                raise ValueError(f"velocity {v.shape} and force {f.shape} differ in shape.")
            for q, qd in zip(coordinates, rates):
                Q[q] += (v.diff(qd).T * f)[0, 0]
    return {q: compact(expr) for q, expr in Q.items()}
