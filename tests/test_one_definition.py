"""One definition of each unit constant, angle wrap, orbital period and mean motion in the
code.

The unit and time constants live in ovtraj/units.py, the reduction of an angle to one turn
in ovtraj/astro/angles.py (``wrap_to_two_pi``, ``wrap_to_pi``, ``principal_angle``) and the
Keplerian period and the mean motion in ``ovtraj.astro.elements`` (``orbital_period``,
``mean_motion``). A copy elsewhere drifts from
its kernel: a bare ``x % TWO_PI`` returns 2 pi itself for a tiny negative ``x``, where the
kernel returns 0. The check reads every module of the library and of its Prefect adapters
(``ovtraj/``, ``flows/``, ``tasks/``) with :mod:`ast` (so comments, docstrings and messages
never count) and names each copy by file and line:

* a number that can only be a unit constant (3600, 86400, 2451545, 36525, 2400000.5, pi/180,
  180/pi and their reciprocals, from the values of ovtraj/units.py itself), written
  anywhere outside ovtraj/units.py but as a bound of a setting's schema (``le=86400``);
* a name for a unit (``KM``, ``PER_KM``, ``KIB``, ``MIB``...) given 1000, 1e-3 or a power
  of 1024 outside ovtraj/units.py (1000 alone is also a penalty or a scale factor, so the
  name decides);
* a reduction by whole turns outside ovtraj/astro/angles.py: ``x % TWO_PI`` (or ``// TWO_PI``)
  and ``np.mod``, ``np.fmod``, ``np.remainder``, ``math.fmod``, ``math.remainder``,
  ``divmod`` by a turn (``TWO_PI``, ``2 * pi``, ``tau``);
* a Keplerian period (a turn, or pi for a half period, times ``sqrt(... ** 3 ...)``)
  outside ``orbital_period``;
* a mean motion (``sqrt`` of a quotient whose divisor is a cube, ``sqrt(mu / a**3)``)
  outside ``mean_motion``.
"""

from __future__ import annotations

import ast
import math
import re
from pathlib import Path

import pytest

from ovtraj import units

ROOT = Path(__file__).resolve().parents[1]
SCANNED = ("ovtraj", "flows", "tasks")
UNITS_MODULE = "ovtraj/units.py"
ANGLES_MODULE = "ovtraj/astro/angles.py"
PERIOD_KERNEL = ("ovtraj/astro/elements.py", "orbital_period")
MEAN_MOTION_KERNEL = ("ovtraj/astro/elements.py", "mean_motion")
FROM_UNITS = "import it from ovtraj.units"

# Values no other figure has: written anywhere, they are a unit constant.
_UNMISTAKABLE = {
    units.S_PER_HOUR: "S_PER_HOUR",
    units.S_PER_DAY: "S_PER_DAY",
    units.J2000_JD: "J2000_JD",
    units.DAYS_PER_JULIAN_CENTURY: "DAYS_PER_JULIAN_CENTURY",
    units.S_PER_JULIAN_CENTURY: "S_PER_JULIAN_CENTURY",
    units.JD_MINUS_MJD: "JD_MINUS_MJD",
    units.RAD_PER_DEG: "RAD_PER_DEG",
    units.DEG_PER_RAD: "DEG_PER_RAD",
}
# The reciprocals first: 1 / RAD_PER_DEG is DEG_PER_RAD's float, named as that.
UNMISTAKABLE = {
    **{1.0 / value: f"1 / {name}" for value, name in _UNMISTAKABLE.items()},
    **_UNMISTAKABLE,
}
# Values that are units only under a unit's name.
NAMED = {
    units.M_PER_KM: "M_PER_KM",
    1.0 / units.M_PER_KM: "1 / M_PER_KM",
    float(units.BYTES_PER_KIB): "BYTES_PER_KIB",
    float(units.BYTES_PER_MIB): "BYTES_PER_MIB",
    float(units.BYTES_PER_GIB): "BYTES_PER_GIB",
}
UNIT_NAME = re.compile(r"(^|_)(KM|KILO(METRE|METER)?S?|[KMG]IB|[KMG]B)(_|$)|_PER_KM\b", re.I)

WRAP_FUNCTIONS = {
    ("np", "mod"),
    ("np", "fmod"),
    ("np", "remainder"),
    ("np", "divmod"),
    ("np", "floor_divide"),
    ("math", "fmod"),
    ("math", "remainder"),
}
_MODULE_ALIASES = {"numpy": "np", "np": "np", "math": "math"}
SCHEMA_BOUNDS = {"ge", "gt", "le", "lt"}


def _number(node: ast.AST) -> float | None:
    """The value of a constant numeric expression (numbers, pi, tau, + - * / **), else None."""
    if isinstance(node, ast.Constant):
        value = node.value
        if isinstance(value, int | float) and not isinstance(value, bool):
            return float(value)
        return None
    if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name):
        if node.value.id in _MODULE_ALIASES and node.attr in ("pi", "tau"):
            return math.pi if node.attr == "pi" else math.tau
        return None
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        value = _number(node.operand)
        return None if value is None else -value
    if isinstance(node, ast.BinOp):
        left, right = _number(node.left), _number(node.right)
        if left is None or right is None:
            return None
        operations = {
            ast.Add: lambda: left + right,
            ast.Sub: lambda: left - right,
            ast.Mult: lambda: left * right,
            ast.Div: lambda: left / right,
            ast.Pow: lambda: left**right,
            ast.LShift: lambda: float(int(left) << int(right)),
        }
        operation = operations.get(type(node.op))
        try:
            return None if operation is None else float(operation())
        except (ArithmeticError, ValueError):
            return None
    return None


def _is_turn(node: ast.AST) -> bool:
    """``TWO_PI`` (any module's), ``tau`` or a number equal to 2 pi."""
    if isinstance(node, ast.Name) and (node.id.endswith("TWO_PI") or node.id.upper() == "TAU"):
        return True
    if isinstance(node, ast.Attribute) and node.attr.endswith("TWO_PI"):
        return True
    return _number(node) == math.tau


def _is_half_turn(node: ast.AST) -> bool:
    return _number(node) == math.pi


def _function(call: ast.Call) -> tuple[str, str] | None:
    """(module alias, name) of ``np.mod(...)``-like calls; ("", name) for a bare name."""
    func = call.func
    if isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name):
        alias = _MODULE_ALIASES.get(func.value.id)
        return None if alias is None else (alias, func.attr)
    if isinstance(func, ast.Name):
        return ("", func.id)
    return None


def _has_cube(node: ast.AST) -> bool:
    return any(
        isinstance(n, ast.BinOp) and isinstance(n.op, ast.Pow) and _number(n.right) == 3.0
        for n in ast.walk(node)
    )


def _is_sqrt_of_cube(node: ast.AST) -> bool:
    if not isinstance(node, ast.Call) or not node.args:
        return False
    function = _function(node)
    return function is not None and function[1] == "sqrt" and _has_cube(node.args[0])


def _is_mean_motion(node: ast.Call) -> bool:
    """``sqrt(x / y)`` with a cube in ``y``: sqrt(mu / a**3)."""
    function = _function(node)
    if function is None or function[1] != "sqrt" or not node.args:
        return False
    quotient = node.args[0]
    return (
        isinstance(quotient, ast.BinOp)
        and isinstance(quotient.op, ast.Div)
        and _has_cube(quotient.right)
    )


def _factors(node: ast.AST) -> list[ast.AST]:
    """The factors of a product ``a * b * c`` (one factor for anything else)."""
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Mult):
        return _factors(node.left) + _factors(node.right)
    return [node]


class _Finder(ast.NodeVisitor):
    """Collects (line, what) for every copy in one module."""

    def __init__(self, path: str) -> None:
        self.path = path
        self.found: set[tuple[int, str]] = set()
        self.functions: list[str] = []

    def _add(self, node: ast.AST, what: str) -> None:
        self.found.add((node.lineno, what))

    def visit_FunctionDef(self, node: ast.FunctionDef) -> None:
        self.functions.append(node.name)
        self.generic_visit(node)
        self.functions.pop()

    visit_AsyncFunctionDef = visit_FunctionDef  # type: ignore[assignment]

    def _check_number(self, node: ast.AST) -> bool:
        value = _number(node)
        if value is not None and value in UNMISTAKABLE and self.path != UNITS_MODULE:
            self._add(node, f"{UNMISTAKABLE[value]} written as a number; {FROM_UNITS}")
            return True
        return False

    def visit_Constant(self, node: ast.Constant) -> None:
        self._check_number(node)

    def visit_Assign(self, node: ast.Assign | ast.AnnAssign) -> None:
        targets = node.targets if isinstance(node, ast.Assign) else [node.target]
        value = None if node.value is None else _number(node.value)
        if value in NAMED and self.path != UNITS_MODULE:
            for target in targets:
                name = getattr(target, "id", getattr(target, "attr", ""))
                if UNIT_NAME.search(name):
                    self._add(node, f"{name} = {NAMED[value]} defined again; {FROM_UNITS}")
        self.generic_visit(node)

    visit_AnnAssign = visit_Assign  # type: ignore[assignment]

    def visit_BinOp(self, node: ast.BinOp) -> None:
        if self._check_number(node):
            return  # its parts are the same number's parts
        if isinstance(node.op, ast.Mod | ast.FloorDiv) and _is_turn(node.right):
            self._wrap(node, "a modulo by a turn")
        if isinstance(node.op, ast.Mult) and self._period(node):
            self._add(node, "an orbital period written inline; use orbital_period")
        self.generic_visit(node)

    def visit_Call(self, node: ast.Call) -> None:
        function = _function(node)
        wraps = function in WRAP_FUNCTIONS or function == ("", "divmod")
        if wraps and len(node.args) >= 2 and _is_turn(node.args[1]):
            self._wrap(node, f"{'.'.join(filter(None, function))}(..., a turn)")
        here = (self.path, self.functions[-1] if self.functions else "")
        if here != MEAN_MOTION_KERNEL and _is_mean_motion(node):
            self._add(node, "a mean motion written inline; use mean_motion")
        # The bounds of a setting's schema (``bounded(unit="s", le=86400)``: at most a day)
        # are limits of a figure stated in its unit, not conversions: their numbers are
        # not read (an expression inside one still is, as everywhere).
        self.visit(node.func)
        for argument in node.args:
            self.visit(argument)
        for keyword in node.keywords:
            if keyword.arg in SCHEMA_BOUNDS and _number(keyword.value) is not None:
                continue
            self.visit(keyword.value)

    def _wrap(self, node: ast.AST, what: str) -> None:
        if self.path != ANGLES_MODULE:
            self._add(node, f"{what}; wrap through ovtraj.astro.angles")

    def _period(self, node: ast.BinOp) -> bool:
        if (self.path, self.functions[-1] if self.functions else "") == PERIOD_KERNEL:
            return False
        factors = _factors(node)
        turns = any(_is_turn(f) or _is_half_turn(f) for f in factors)
        return turns and any(_is_sqrt_of_cube(f) for f in factors)


def copies(source: str, path: str) -> list[str]:
    """``path:line: what`` for every copy in ``source`` (the text of the module at ``path``)."""
    finder = _Finder(path)
    finder.visit(ast.parse(source, filename=path))
    # A product a * b * c is visited at each of its BinOps: report a line's finding once.
    return [f"{path}:{line}: {what}" for line, what in sorted(finder.found)]


def _modules() -> list[Path]:
    return sorted(
        p
        for folder in SCANNED
        for p in (ROOT / folder).rglob("*.py")
        if "__pycache__" not in p.parts
    )


def test_the_scan_reads_the_library_and_its_adapters():
    names = {p.relative_to(ROOT).as_posix() for p in _modules()}
    assert {UNITS_MODULE, ANGLES_MODULE, PERIOD_KERNEL[0], "flows/common.py"} <= names
    assert any(name.startswith("tasks/") for name in names)


def test_no_copy_of_a_unit_constant_an_angle_wrap_or_a_period_in_the_code():
    found = []
    for module in _modules():
        found += copies(module.read_text(encoding="utf-8"), module.relative_to(ROOT).as_posix())
    assert found == [], "\n".join(found)


PLANTED = """\
import math
import numpy as np
from ovtraj.astro.angles import TWO_PI
_HOUR = 3600.0
METRES_PER_KM = 1000.0
heading = math.atan2(1.0, -1.0) % TWO_PI
raan = np.mod(heading - 7.0, TWO_PI)
phase = math.fmod(heading, 2.0 * math.pi)
period = TWO_PI * math.sqrt(7e6**3 / 3.986e14)
deg = math.pi / 180.0
t = (2451545.0 - 2451000.0) / 36525.0
horizon = 3 * TWO_PI * np.sqrt(a**3 / mu)
turns, angle = divmod(heading, 2 * np.pi)
step_s = bounded(unit="s", le=3600, default=2 * 86400.0)
n = math.sqrt(3.986e14 / a**3)
"""
# What the check must not take for a copy: the kernels, the constants imported, numbers
# that are no unit (a penalty of 1000 under its own name, a modulo by a period).
CLEAN = """\
import math
from ovtraj.astro.angles import TWO_PI, wrap_to_two_pi
from ovtraj.astro.elements import orbital_period
from ovtraj.units import M_PER_KM, S_PER_HOUR
_FAILURE = 1.0e3
span_s = 2.0 * S_PER_HOUR
heading = wrap_to_two_pi(math.atan2(1.0, -1.0))
phase = TWO_PI * (wait % period) / period
altitude_km = 400e3 / M_PER_KM
period = orbital_period(7e6, mu=3.986e14)
time_scale_s = math.sqrt(radius**3 / mu)
label = "T = 2 pi sqrt(a**3 / mu), 3600 s per hour, x % TWO_PI"
time_limit_s: float = bounded(unit="s", gt=0, le=7 * 86400)
"""


def test_the_check_finds_each_planted_copy_by_file_and_line():
    found = copies(PLANTED, "ovtraj/planted.py")
    lines = sorted({int(line.split(":")[1]) for line in found})
    assert lines == [4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15]
    assert f"ovtraj/planted.py:4: S_PER_HOUR written as a number; {FROM_UNITS}" in found
    assert any(line.startswith("ovtraj/planted.py:5: METRES_PER_KM = M_PER_KM") for line in found)
    assert any(line.startswith("ovtraj/planted.py:6: a modulo by a turn") for line in found)
    assert any(line.startswith("ovtraj/planted.py:7: np.mod(") for line in found)
    assert any(line.startswith("ovtraj/planted.py:8: math.fmod(") for line in found)
    assert any("9: an orbital period" in line for line in found)
    assert any("10: RAD_PER_DEG" in line for line in found)
    assert {w for w in found if ":11:" in w} == {
        f"ovtraj/planted.py:11: J2000_JD written as a number; {FROM_UNITS}",
        f"ovtraj/planted.py:11: DAYS_PER_JULIAN_CENTURY written as a number; {FROM_UNITS}",
    }
    assert any("12: an orbital period" in line for line in found)
    assert any(line.startswith("ovtraj/planted.py:13: divmod(") for line in found)
    # A schema bound (le=3600) is a limit, not a conversion; the default beside it is.
    assert [w for w in found if ":14:" in w] == [
        f"ovtraj/planted.py:14: S_PER_DAY written as a number; {FROM_UNITS}"
    ]
    assert [w for w in found if ":15:" in w] == [
        "ovtraj/planted.py:15: a mean motion written inline; use mean_motion"
    ]


def test_the_check_leaves_the_kernels_and_other_numbers_alone():
    assert copies(CLEAN, "ovtraj/clean.py") == []


@pytest.mark.parametrize(
    ("path", "source"),
    [
        (UNITS_MODULE, "S_PER_HOUR = 3600.0\nM_PER_KM = 1000.0\n"),
        (ANGLES_MODULE, "def wrap(angle):\n    return angle % TWO_PI\n"),
        (PERIOD_KERNEL[0], "def orbital_period(a, mu):\n    return TWO_PI * np.sqrt(a**3 / mu)\n"),
        (MEAN_MOTION_KERNEL[0], "def mean_motion(a, mu):\n    return np.sqrt(mu / a**3)\n"),
    ],
)
def test_each_definition_is_allowed_in_its_own_home_only(path, source):
    assert copies(source, path) == []
    assert copies(source, "ovtraj/elsewhere.py") != []
