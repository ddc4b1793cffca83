"""Legendre-Gauss (LG) and Legendre-Gauss-Radau (LGR) collocation on [-1, 1].

Nodes, quadrature weights and differentiation matrices of the Gauss pseudospectral
method (Benson et al., JGCD 29(6), 2006; Huntington, MIT PhD thesis 2007, ch. 4, the
seed's reference [6]) and of the Radau pseudospectral method (Garg et al., Automatica
46(11), 2010). A scheme of ``n`` collocation points approximates the state by the
Lagrange polynomial through its *support points*:

* **LG**: support ``[-1, tau_1 .. tau_n]`` (the ``n`` roots of ``P_n`` and the initial
  point), collocation at the roots; the final state is not a support point and follows
  from Gauss quadrature of the dynamics, ``x(1) = x(-1) + sum w_k f_k`` (seed eq. 23).
  The weights integrate polynomials of degree ``2n - 1`` exactly.
* **LGR**: support ``[tau_1 = -1 .. tau_n, +1]`` (the roots of ``P_{n-1} + P_n``, plus
  the final point), collocation at the ``n`` Radau points; the final state is a support
  point. The weights are exact to degree ``2n - 2``.

In both cases the differentiation matrix ``D`` is ``n x (n + 1)``: row ``k`` holds the
derivatives at collocation point ``k`` of the ``n + 1`` Lagrange basis polynomials of the
support points (seed eq. 22), computed in barycentric form (Berrut & Trefethen, SIAM
Review 46(3), 2004, eqs. 3.2 and 9.4), which is stable for the node counts used here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.polynomial import legendre
from numpy.typing import ArrayLike, NDArray
from scipy.special import eval_legendre, roots_jacobi

__all__ = [
    "CollocationScheme",
    "barycentric_weights",
    "collocation_scheme",
    "differentiation_matrix",
    "legendre_gauss",
    "legendre_gauss_radau",
]

SchemeKind = Literal["lg", "lgr"]


def legendre_gauss(n: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The ``n`` Legendre-Gauss nodes (roots of ``P_n``, ascending) and weights.

    Exact for polynomials of degree ``2n - 1`` (Abramowitz & Stegun 25.4.29).
    """
    if n < 1:
        raise ValueError(f"n must be at least 1, got {n}")
    nodes, weights = legendre.leggauss(n)
    return nodes, weights


def legendre_gauss_radau(n: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The ``n`` flipped Legendre-Gauss-Radau nodes (``-1`` included, ``+1`` not) and weights.

    The other nodes are the roots of the Jacobi polynomial ``P_{n-1}^{(0,1)}``; the
    weights are ``2 / n^2`` at ``-1`` and ``(1 - tau) / (n P_{n-1}(tau))^2`` elsewhere
    (Abramowitz & Stegun 25.4.31). Exact for polynomials of degree ``2n - 2``.
    """
    if n < 1:
        raise ValueError(f"n must be at least 1, got {n}")
    if n == 1:
        return np.array([-1.0]), np.array([2.0])
    interior, _ = roots_jacobi(n - 1, 0.0, 1.0)
    nodes = np.concatenate(([-1.0], np.sort(interior)))
    weights = np.empty(n)
    weights[0] = 2.0 / n**2
    tail = nodes[1:]
    weights[1:] = (1.0 - tail) / (n * eval_legendre(n - 1, tail)) ** 2
    return nodes, weights


def barycentric_weights(points: ArrayLike) -> NDArray[np.float64]:
    """``w_j = 1 / prod_{k != j} (x_j - x_k)``, scaled by its largest magnitude.

    The common scale cancels in every barycentric formula (Berrut & Trefethen eq. 3.2).
    """
    x = np.asarray(points, dtype=float)
    diff = x[:, None] - x[None, :]
    np.fill_diagonal(diff, 1.0)
    # Products of logs would avoid overflow for hundreds of points; tens are fine.
    w = 1.0 / np.prod(diff, axis=1)
    return w / np.max(np.abs(w))


def _square_differentiation(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """Derivatives at the support points of their Lagrange basis (Berrut & Trefethen 9.4)."""
    w = barycentric_weights(points)
    diff = points[:, None] - points[None, :]
    np.fill_diagonal(diff, 1.0)
    d = (w[None, :] / w[:, None]) / diff
    np.fill_diagonal(d, 0.0)
    # The negative row sum makes D annihilate constants to round-off.
    np.fill_diagonal(d, -d.sum(axis=1))
    return d


def differentiation_matrix(support: ArrayLike, at: ArrayLike) -> NDArray[np.float64]:
    """``D[k, i] = L_i'(at_k)`` for the Lagrange basis ``L_i`` of ``support``.

    Every ``at`` point must be a support point (the case of collocation).
    """
    support = np.asarray(support, dtype=float)
    at = np.asarray(at, dtype=float)
    rows = [int(np.argmin(np.abs(support - a))) for a in at]
    if not np.allclose(support[rows], at, rtol=0.0, atol=1e-13):
        raise ValueError("every evaluation point must be a support point")
    return _square_differentiation(support)[rows]


@dataclass(frozen=True)
class CollocationScheme:
    """One segment's nodes on [-1, 1] (see the module notes).

    ``support``: the ``n + 1`` points carrying the state polynomial; ``collocation``: the
    ``n`` points where the dynamics hold (``support[colloc_index]``); ``weights``: their
    quadrature weights; ``d``: the ``n x (n + 1)`` differentiation matrix;
    ``end_by_quadrature``: the final point is not a support point (LG) and the final
    state is given by quadrature.
    """

    kind: SchemeKind
    n: int
    support: NDArray[np.float64]
    collocation: NDArray[np.float64]
    colloc_index: NDArray[np.intp]
    weights: NDArray[np.float64]
    d: NDArray[np.float64]
    end_by_quadrature: bool

    def integration_matrix(self) -> NDArray[np.float64]:
        """``A`` with ``x(support[j]) = x(-1) + sum_k A[j - 1, k] f_k`` for ``j >= 1``.

        The integral form of the collocation equations (LG: Benson et al. 2006, eq. 27;
        LGR: Garg et al. 2010, sec. 4): ``A`` is the inverse of ``D`` without its first
        column, since ``D`` annihilates constants. For LG the rows give the state at the
        collocation points (the final state is the quadrature); for LGR at the Radau
        points after ``-1`` and at ``+1``.
        """
        return np.linalg.inv(self.d[:, 1:])


def collocation_scheme(kind: SchemeKind, n: int) -> CollocationScheme:
    """The LG or LGR scheme with ``n`` collocation points."""
    if kind == "lg":
        nodes, weights = legendre_gauss(n)
        support = np.concatenate(([-1.0], nodes))
        index = np.arange(1, n + 1)
        end_by_quadrature = True
    elif kind == "lgr":
        nodes, weights = legendre_gauss_radau(n)
        support = np.concatenate((nodes, [1.0]))
        index = np.arange(n)
        end_by_quadrature = False
    else:
        raise ValueError(f"unknown collocation scheme {kind!r} (use 'lg' or 'lgr')")
    return CollocationScheme(
        kind=kind,
        n=n,
        support=support,
        collocation=nodes,
        colloc_index=index,
        weights=weights,
        d=differentiation_matrix(support, nodes),
        end_by_quadrature=end_by_quadrature,
    )
