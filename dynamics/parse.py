"""Reading model options given as text (a curve, a potential, constraint coefficients) without
running any code.

`sympy.sympify` evaluates its string with Python's `eval`, so a crafted option could run
anything. Here the text is parsed into a Python syntax tree and only arithmetic on numbers,
names and calls of the elementary functions below is turned into sympy objects; attribute
access, subscripts, keywords, lambdas and every other construct are refused.
"""

from __future__ import annotations

import ast
import operator

import sympy as sp

FUNCTIONS = {
    name: getattr(sp, name)
    for name in (
        "sin cos tan cot sec csc asin acos atan atan2 sinh cosh tanh asinh acosh atanh "
        "exp log sqrt Abs sign"
    ).split()
}
FUNCTIONS["abs"] = sp.Abs
CONSTANTS = {"pi": sp.pi, "E": sp.E}
MAX_LENGTH = 2000
MAX_EXPONENT = 100  # a literal power beyond this (9**9**9) would take forever to evaluate

_BINARY = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
    ast.Pow: operator.pow,
}
_UNARY = {ast.USub: operator.neg, ast.UAdd: operator.pos}


def parse_expression(value, what: str) -> sp.Expr:
    """`value` as a sympy expression: a sympy expression or real number as it is, or text
    of arithmetic (+ - * / ** ^), numbers, names (plain symbols, or pi and E) and calls of
    `FUNCTIONS`. ValueError naming `what` for anything else; no code is run."""
    if isinstance(value, sp.Basic):
        return value
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return sp.sympify(value)
    if not isinstance(value, str):
        raise TypeError(f"{what} must be a sympy expression or text, got {value!r}.")
    if len(value) > MAX_LENGTH:
        raise ValueError(f"{what} is longer than {MAX_LENGTH} characters.")
    try:
        tree = ast.parse(value.strip().replace("^", "**"), mode="eval")  # x^2: as sympify
    except SyntaxError as exc:
        raise ValueError(f"cannot read {what} {value!r}: {exc.msg}.") from None
    try:
        return _convert(tree.body)
    except _Refused as exc:
        raise ValueError(f"cannot read {what} {value!r}: {exc}") from None


class _Refused(Exception):
    pass


def _convert(node: ast.AST) -> sp.Expr:
    if isinstance(node, ast.Constant):
        if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
            raise _Refused(f"{node.value!r} is not a real number.")
        return sp.Integer(node.value) if isinstance(node.value, int) else sp.Float(node.value)
    if isinstance(node, ast.Name):
        if node.id in CONSTANTS:
            return CONSTANTS[node.id]
        if node.id.startswith("_") or node.id in FUNCTIONS:
            raise _Refused(f"{node.id!r} is not a symbol name.")
        return sp.Symbol(node.id)
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        left, right = _convert(node.left), _convert(node.right)
        if isinstance(node.op, ast.Pow) and right.is_number:
            if abs(float(right)) > MAX_EXPONENT:
                raise _Refused(f"the exponent {right} is too large.")
        return _BINARY[type(node.op)](left, right)
    if isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
        return _UNARY[type(node.op)](_convert(node.operand))
    if isinstance(node, ast.Call):
        name = node.func.id if isinstance(node.func, ast.Name) else None
        if name not in FUNCTIONS or node.keywords:
            allowed = ", ".join(sorted(FUNCTIONS))
            raise _Refused(f"only calls of {allowed} are allowed, got {ast.unparse(node)!r}.")
        if any(isinstance(a, ast.Starred) for a in node.args):
            raise _Refused(f"{ast.unparse(node)!r} unpacks arguments.")
        try:
            return FUNCTIONS[name](*(_convert(a) for a in node.args))
        except TypeError as exc:
            raise _Refused(f"{ast.unparse(node)!r}: {exc}") from None
    raise _Refused(f"{ast.unparse(node)!r} is not arithmetic on numbers, symbols and functions.")
