"""The safe formula language of implicit surfaces: what it builds and what it rejects."""
import math
import time

import casadi as ca
import numpy as np
import pytest

from symcushion.model.formula import MAX_CONSTANT, MAX_EXPONENT, FormulaError, parse_formula

POINT = np.array([0.3, -0.7, 1.9])


def value(text, p=POINT):
    x = ca.SX.sym("x", 3)
    f = ca.Function("phi", [x], [parse_formula(text)(x)])
    return float(f(p))


@pytest.mark.parametrize("text, expected", [
    ("x**2 + y**2 + z - 5", lambda x, y, z: x * x + y * y + z - 5),
    ("-z**-2 + 3*x/y", lambda x, y, z: -z ** -2 + 3 * x / y),
    ("sqrt(x*x + y*y) - e**0.5 * pi", lambda x, y, z: math.hypot(x, y) - math.e ** 0.5 * math.pi),
    ("atan2(y, x) + min(x, z) - max(y, z)",
     lambda x, y, z: math.atan2(y, x) + min(x, z) - max(y, z)),
    ("exp(x) + log(z) + sin(y) * cos(z) - tan(x)",
     lambda x, y, z: math.exp(x) + math.log(z) + math.sin(y) * math.cos(z) - math.tan(x)),
    ("fabs(y) + abs(y) + sinh(x) + cosh(x) + tanh(z) + hypot(x, y)",
     lambda x, y, z: 2 * abs(y) + math.sinh(x) + math.cosh(x) + math.tanh(z) + math.hypot(x, y)),
    ("asin(x) + acos(x) + atan(y) + +z", lambda x, y, z: math.pi / 2 + math.atan(y) + z),
])
def test_formula_matches_python(text, expected):
    assert value(text) == pytest.approx(expected(*POINT), rel=1e-14, abs=1e-14)


def test_formula_gradient_by_ad():
    x = ca.SX.sym("x", 3)
    expr = parse_formula("x**2 + y**2 + z**3")(x)
    grad = np.asarray(ca.Function("g", [x], [ca.gradient(expr, x)])(POINT)).ravel()
    np.testing.assert_allclose(grad, [2 * POINT[0], 2 * POINT[1], 3 * POINT[2] ** 2], rtol=1e-14)


def test_constant_division_by_zero_is_inf_not_a_traceback():
    assert math.isinf(value("1/0 + z"))


@pytest.mark.parametrize("text, needle", [
    ("x**2 + ", "invalid syntax"),
    ("z - 9**9**9", "exponent '9 ** 9' is not a plain number"),
    ("z**x", "not a plain number"),
    (f"x**{MAX_EXPONENT + 1}", "exceeds"),
    ("9e99*z", "exceeds"),
    (f"{MAX_CONSTANT * 10:g} + z", "exceeds"),
    ("__import__('os').system('true')", "unknown function"),
    ("__import__('os')", "unknown function '__import__'"),
    ("open('x')", "unknown function 'open'"),
    ("q + z", "unknown name 'q'"),
    ("x.real", "Attribute"),
    ("[x, y][0]", "Subscript"),
    ("lambda: 1", "Lambda"),
    ("x if y else z", "IfExp"),
    ("x < y", "Compare"),
    ("x % 2", "BinOp"),
    ("sin(x, y)", "takes 1"),
    ("sin(x=1)", "takes 1"),
    ("True * z", "not a real number"),
    ("1j * z", "not a real number"),
    ("", "empty"),
    ("(" * 1500 + "z" + ")" * 1500, "longer than"),
    ("-" * 200 + "z", "nested deeper"),
])
def test_formula_rejections_name_the_field(text, needle):
    started = time.perf_counter()
    with pytest.raises(FormulaError) as info:
        parse_formula(text, "obstacle[2].phi")
    assert time.perf_counter() - started < 1.0
    message = str(info.value)
    assert message.startswith("`obstacle[2].phi`") and needle in message, message


def test_formula_rejects_non_strings():
    with pytest.raises(FormulaError, match="must be a formula string"):
        parse_formula(3.0, "phi")
