"""Angles: the full turn and the reduction of an angle to one turn.

Three interval conventions, one function each (angles in rad):

* :func:`wrap_to_pi`: [-pi, pi) (up to rounding, see there), for differences of angles
  (errors, offsets);
* :func:`wrap_to_two_pi`: [0, 2 pi), for angles measured from a reference direction
  (headings, sidereal angles, orbital elements) and for angles ahead (the turn to go);
* :func:`principal_angle`: (-pi, pi], the principal value of ``atan2`` and
  ``numpy.angle``, computed exactly (IEEE remainder).

Whole turns are turns of the float ``TWO_PI``, 2.4e-16 rad short of the real 2 pi: an
angle of n turns is reduced as n float turns (an offset of n * 2.4e-16 rad from the real
reduction, irrelevant for the few turns an orbit's angles make).

:func:`wrap_to_pi` and :func:`wrap_to_two_pi` are plain arithmetic on floats, so the same
functions also run compiled by numba (``numba.njit(wrap_to_pi)``,
:mod:`ovtraj.reentry.dynamics`). A bare ``x % TWO_PI`` is the modulo of Python and numpy
(the sign of the divisor); it can give 2 pi itself for a negative ``x`` within half an
ulp of 0 (-4.4e-16 < x < 0), which :func:`wrap_to_two_pi` maps to 0; for every other
``x`` the two give the same float (-0.0 gives 0.0, NaN and infinities give NaN, in both).
No module wraps an angle by its own modulo (tests/test_one_definition.py).

References
----------
IEEE 754-2008, sec. 5.3.1 (``remainder``: exact, the quotient rounded to nearest even).
Python Language Reference, sec. 6.7 (``%`` on floats; numpy's ``mod`` gives the same).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

__all__ = ["TWO_PI", "principal_angle", "wrap_to_pi", "wrap_to_two_pi"]

TWO_PI = 2.0 * math.pi
"""One full turn [rad]."""


def wrap_to_pi(angle: float | NDArray[np.float64]) -> float | NDArray[np.float64]:
    """``angle`` reduced by whole turns to [-pi, pi) [rad]: ``(angle + pi) mod 2 pi - pi``.

    Takes a float (the result is a float of the same type: a Python float stays one, a
    numpy scalar stays one) or a numpy array (elementwise; an array back). The modulo is
    exact, the ``+ pi`` and ``- pi`` round: the result is off by up to an ulp of
    ``|angle| + pi`` (4.4e-16 rad for |angle| < pi; ``wrap_to_pi(1e-17)`` is 0.0), and at
    the ends that rounding can land on the other end: the float below pi gives -pi, the
    float below -pi gives pi itself. Runs compiled by numba as well.
    """
    return (angle + math.pi) % TWO_PI - math.pi


def wrap_to_two_pi(angle: float | NDArray[np.float64]) -> float | NDArray[np.float64]:
    """``angle`` reduced by whole turns to [0, 2 pi) [rad].

    Takes a float (the result is a float of the same type) or a numpy array (elementwise).
    The modulo alone returns 2 pi for a negative ``angle`` within half an ulp of 0
    (``-1e-17 + 2 pi`` rounds to ``2 pi``); that result is mapped to 0 by multiplying
    with the comparison (1 or 0), which keeps the argument's type where ``numpy.where``
    would make a float an array, and compiles in numba. Every other result is the
    modulo's, bit for bit. Runs compiled by numba as well.
    """
    wrapped = angle % TWO_PI
    return wrapped * (wrapped < TWO_PI)


def principal_angle(angle: float) -> float:
    """``angle`` reduced by whole turns to (-pi, pi] [rad], exactly.

    ``math.remainder(angle, 2 pi)`` (IEEE 754 remainder: exact, within [-pi, pi]) with
    -pi mapped to pi, the range of ``atan2``. Floats only.
    """
    wrapped = math.remainder(angle, TWO_PI)
    return math.pi if wrapped == -math.pi else wrapped
