"""A second, independent integrator: scipy's DOP853 on the same equations.

Used by tests (a second method) and by ``benchmarks/propagation.py``; the
project's propagator is :mod:`ovtraj.astro.propagation.taylor`.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from ovtraj.astro.propagation.gravity import two_body_j2_rhs


def propagate_dop853(
    state0: np.ndarray,
    t0: float,
    t1: float,
    *,
    mu: float,
    radius: float,
    j2: float,
    rtol: float,
    atol: float,
    t_eval: np.ndarray | None = None,
) -> np.ndarray:
    """Propagate a Cartesian ECI state (m, m/s) from ``t0`` to ``t1`` [s] with DOP853.

    Returns the final state (6,) or, with ``t_eval``, the states at those times (n, 6).
    """

    def rhs(_t: float, s: np.ndarray) -> np.ndarray:
        return two_body_j2_rhs(s, mu=mu, radius=radius, j2=j2)

    sol = solve_ivp(
        rhs,
        (t0, t1),
        np.asarray(state0, dtype=float),
        method="DOP853",
        rtol=rtol,
        atol=atol,
        t_eval=t_eval,
    )
    if not sol.success:
        raise RuntimeError(f"DOP853 failed: {sol.message}")
    return sol.y.T if t_eval is not None else sol.y[:, -1]
