"""Straight-line programs: a model's expressions as one list of shared assignments.

`Program` runs sympy's common-subexpression elimination once over every expression that the
generated kernels evaluate (mass/constraint matrix, right-hand side, energy, constraint
residual, power, outputs), so that each kernel prints only the assignments its own results
need, and a subexpression shared between, say, M and the energy is found once.

`Program.derivatives` differentiates results by the chain rule through the assignments
(forward mode): each assignment c = e(a, b, ...) gets dc/dv = sum_a (de/da) (da/dv), with
de/da a derivative of one small expression. This gives the Jacobians for the linearisation
exactly, from the same program, instead of differentiating the full expressions of M and F
again (whose derivatives grow with the square of their size).
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp

from .calculus import diff


class Program:
    """Assignments `steps` [(symbol, expression)] in order, and `results` by group name:
    each group's expressions rewritten in the assigned symbols and the inputs."""

    def __init__(self, groups: dict[str, Sequence], prefix: str = "c"):
        names = list(groups)
        flat = [sp.sympify(e) for name in names for e in groups[name]]
        steps, reduced = sp.cse(flat, symbols=sp.numbered_symbols(prefix), optimizations=None)
        self.steps: list[tuple[sp.Symbol, sp.Expr]] = list(steps)
        self.results: dict[str, list] = {}
        i = 0
        for name in names:
            size = len(groups[name])
            self.results[name] = list(reduced[i : i + size])
            i += size
        self._prefix = prefix

    def needed(self, exprs: Sequence) -> list[tuple[sp.Symbol, sp.Expr]]:
        """The assignments that `exprs` depend on, in program order."""
        assigned = {s for s, _ in self.steps}
        want = set().union(*(sp.sympify(e).free_symbols for e in exprs)) & assigned
        keep = []
        for s, e in reversed(self.steps):
            if s in want:
                keep.append((s, e))
                want |= e.free_symbols & assigned
        return keep[::-1]

    def derivatives(
        self, exprs: Sequence, wrt: Sequence, prefix: str = "d"
    ) -> tuple[list[tuple[sp.Symbol, sp.Expr]], list[list]]:
        """(steps, D): further assignments, after `self.needed(exprs)`, and `D[i][j]` =
        `d exprs[i] / d wrt[j]` in the program's symbols (0 where it does not depend on it).
        `wrt` are input symbols (never assigned in the program)."""
        index = {v: j for j, v in enumerate(wrt)}
        tangent: dict[sp.Symbol, dict[int, sp.Expr]] = {v: {j: sp.S.One} for v, j in index.items()}
        steps: list[tuple[sp.Symbol, sp.Expr]] = []
        fresh = sp.numbered_symbols(prefix)

        def name(expr):
            """expr itself if it is a number or a symbol, else a new assigned symbol."""
            if expr.is_Atom:
                return expr
            s = next(fresh)
            steps.append((s, expr))
            return s

        def chain(expr) -> dict[int, sp.Expr]:
            total: dict[int, list] = {}
            for a in expr.free_symbols:
                da = tangent.get(a)
                if not da:
                    continue
                partial = diff(expr, a)
                if partial == 0:
                    continue
                if len(da) > 1:
                    partial = name(partial)  # shared by every direction
                for j, dj in da.items():
                    total.setdefault(j, []).append(partial * dj)
            return {j: sp.Add(*terms) for j, terms in total.items()}

        for s, e in self.needed(exprs):
            d = chain(e)
            d = {j: name(v) for j, v in d.items() if v != 0}
            if d:
                tangent[s] = d
        out = []
        for e in exprs:
            d = chain(sp.sympify(e))
            out.append([d.get(j, sp.S.Zero) for j in range(len(wrt))])
        return steps, out
