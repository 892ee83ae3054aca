"""A safe formula language for implicit surfaces φ(x, y, z) given as text.

A scene file may describe an obstacle by a formula such as
``"x**2 + y**2 + z - 5"``. This module owns turning such text into a CasADi
expression *without* ``eval``: the text is parsed by :mod:`ast` and only a
whitelist of nodes is accepted — numbers of bounded magnitude, the names
x, y, z, pi and e, the operators + − * / ** and unary ±, and the functions
of :data:`FUNCTIONS`. Exponents must be plain numbers of bounded magnitude,
so ``9**9**9`` is rejected at once instead of hanging. Every rejection is a
:class:`FormulaError` (a ValueError) naming the field, the text and the rule.

It does not decide whether the surface is sensible (finite and
differentiable near the feet): ``symcushion.run.checks`` samples it.
"""
from __future__ import annotations

import ast
import math

import casadi as ca

__all__ = ["FormulaError", "Formula", "parse_formula", "FUNCTIONS", "NAMES", "MAX_CONSTANT",
           "MAX_EXPONENT", "MAX_LENGTH", "MAX_DEPTH"]

#: Largest magnitude of a number in a formula. Scenes are metre-scale; 1e6
#: allows any coefficient a real surface needs while keeping every
#: intermediate of a bounded-exponent polynomial far from overflow.
MAX_CONSTANT = 1e6

#: Largest magnitude of an exponent (``x**p`` needs a number p, |p| ≤ 8):
#: enough for any polynomial surface; (1e6)**8 = 1e48 stays finite.
MAX_EXPONENT = 8

#: Longest accepted text (characters) and deepest nesting of the parse tree:
#: far above any hand-written surface, low enough that parsing and building
#: cannot exhaust the stack or the memory.
MAX_LENGTH = 2000
MAX_DEPTH = 60

#: Variables and constants a formula may use.
NAMES = ("x", "y", "z", "pi", "e")

#: Functions a formula may call: name → (number of arguments, CasADi builder).
FUNCTIONS = {
    "sqrt": (1, ca.sqrt), "exp": (1, ca.exp), "log": (1, ca.log),
    "sin": (1, ca.sin), "cos": (1, ca.cos), "tan": (1, ca.tan),
    "asin": (1, ca.asin), "acos": (1, ca.acos), "atan": (1, ca.atan),
    "sinh": (1, ca.sinh), "cosh": (1, ca.cosh), "tanh": (1, ca.tanh),
    "fabs": (1, ca.fabs), "abs": (1, ca.fabs),
    "atan2": (2, ca.atan2), "hypot": (2, lambda a, b: ca.sqrt(a * a + b * b)),
    "min": (2, ca.fmin), "max": (2, ca.fmax),
}

_BINARY = {ast.Add: lambda a, b: a + b, ast.Sub: lambda a, b: a - b,
           ast.Mult: lambda a, b: a * b, ast.Div: lambda a, b: a / b}

_ALLOWED = ("numbers (|c| <= {c:g}), x, y, z, pi, e, + - * / **, and the functions "
            "{f}").format(c=MAX_CONSTANT, f=", ".join(sorted(FUNCTIONS)))


class FormulaError(ValueError):
    """A formula that is not in the safe language (names the field and the rule)."""


class Formula:
    """A parsed, checked formula in x, y, z.

    Parameters
    ----------
    text : str
    field : str
        Name shown in messages (``obstacle[0].phi``).

    Calling the formula on a CasADi 3-vector p returns φ(p[0], p[1], p[2]).
    """

    def __init__(self, text: str, field: str = "phi"):
        self.text, self.field = text, field
        self.tree = _parse(text, field)

    def __call__(self, p):
        env = {"x": p[0], "y": p[1], "z": p[2], "pi": ca.DM(math.pi), "e": ca.DM(math.e)}
        value = _Builder(env).visit(self.tree.body)
        if isinstance(value, ca.DM) and isinstance(p, (ca.SX, ca.MX)):
            value = type(p)(value)          # a constant φ: still an expression of p
        return value

    def __repr__(self):
        return f"Formula({self.text!r})"


def parse_formula(text, field: str = "phi") -> Formula:
    """Check ``text`` and return a :class:`Formula` (raises :class:`FormulaError`)."""
    return Formula(text, field)


def _fail(field, text, why) -> FormulaError:
    return FormulaError(f"`{field}` = {text!r} is not a valid formula: {why}; allowed: "
                        f"{_ALLOWED}.")


def _parse(text, field) -> ast.Expression:
    if not isinstance(text, str):
        raise FormulaError(f"`{field}` must be a formula string in x, y, z, got {text!r}.")
    if len(text) > MAX_LENGTH:
        raise _fail(field, text[:40] + "...", f"longer than {MAX_LENGTH} characters")
    if not text.strip():
        raise _fail(field, text, "it is empty")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as exc:
        where = f" at column {exc.offset}" if exc.offset else " (incomplete expression?)"
        raise _fail(field, text, f"{exc.msg}{where}") from None
    except (RecursionError, MemoryError, ValueError):
        raise _fail(field, text, "it is nested too deeply") from None
    _Checker(field, text).visit(tree.body)
    return tree


class _Checker:
    """Walks the tree and rejects every node outside the language."""

    def __init__(self, field, text):
        self.field, self.text = field, text

    def fail(self, why):
        return _fail(self.field, self.text, why)

    def visit(self, node, depth=0):
        if depth > MAX_DEPTH:
            raise self.fail(f"nested deeper than {MAX_DEPTH} levels")
        if isinstance(node, ast.Constant):
            self.number(node.value)
        elif isinstance(node, ast.Name):
            if node.id not in NAMES:
                raise self.fail(f"unknown name {node.id!r}")
        elif isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            self.visit(node.operand, depth + 1)
        elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow):
            self.visit(node.left, depth + 1)
            self.exponent(node.right)
        elif isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            self.visit(node.left, depth + 1)
            self.visit(node.right, depth + 1)
        elif isinstance(node, ast.Call):
            self.call(node, depth)
        else:
            raise self.fail(f"{type(node).__name__} is not allowed")

    def number(self, value):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(f"the constant {value!r} is not a real number")
        if not math.isfinite(value) or abs(value) > MAX_CONSTANT:
            raise self.fail(f"the constant {value!r} exceeds {MAX_CONSTANT:g} in magnitude")

    def exponent(self, node):
        value = _signed_number(node)
        if value is None:
            raise self.fail(f"the exponent {ast.unparse(node)!r} is not a plain number (write "
                            "exp(p*log(x)) for a variable power)")
        if abs(value) > MAX_EXPONENT:
            raise self.fail(f"the exponent {value!r} exceeds {MAX_EXPONENT} in magnitude")

    def call(self, node, depth):
        if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
            name = node.func.id if isinstance(node.func, ast.Name) else ast.unparse(node.func)
            raise self.fail(f"unknown function {name!r}")
        arity = FUNCTIONS[node.func.id][0]
        if node.keywords or len(node.args) != arity:
            raise self.fail(f"{node.func.id} takes {arity} positional argument(s)")
        for arg in node.args:
            self.visit(arg, depth + 1)


def _signed_number(node):
    sign = 1.0
    while isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        sign = -sign if isinstance(node.op, ast.USub) else sign
        node = node.operand
    if isinstance(node, ast.Constant) and not isinstance(node.value, bool) \
            and isinstance(node.value, (int, float)):
        return sign * float(node.value)
    return None


class _Builder:
    """Builds the CasADi expression of a checked tree."""

    def __init__(self, env):
        self.env = env

    def visit(self, node):
        if isinstance(node, ast.Constant):
            # DM, not float: 1/0 between constants is then inf (caught by the
            # finiteness check), not a ZeroDivisionError traceback.
            return ca.DM(float(node.value))
        if isinstance(node, ast.Name):
            return self.env[node.id]
        if isinstance(node, ast.UnaryOp):
            value = self.visit(node.operand)
            return -value if isinstance(node.op, ast.USub) else value
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow):
            return self.visit(node.left) ** _signed_number(node.right)
        if isinstance(node, ast.BinOp):
            return _BINARY[type(node.op)](self.visit(node.left), self.visit(node.right))
        _, build = FUNCTIONS[node.func.id]
        return build(*(self.visit(a) for a in node.args))
