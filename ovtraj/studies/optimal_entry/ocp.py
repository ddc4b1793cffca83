"""A single-phase optimal-control problem in Bolza form, as the transcription sees it.

Minimise ``J = Phi(x(s0), x(sf), sf, p) + integral_{s0}^{sf} L(x, u, s, p) ds`` subject to
``dx/ds = f(x, u, s, p)``, box bounds on ``x``, ``u``, ``p`` and on the boundary states,
path constraints ``c_lo <= c(x, u, s, p) <= c_hi`` and boundary constraints
``b_lo <= b(x(s0), x(sf), sf, p) <= b_hi`` (Betts, *Practical Methods for Optimal Control
and Estimation Using Nonlinear Programming*, 2nd ed., SIAM 2010, sec. 4.1). The
independent variable ``s`` is time (free final value) or the normalised energy of seed
001 (fixed interval [0, 1]). Everything is physical (SI); the scales only condition the
NLP (each variable is divided by its scale, each defect by its state's scale).

Functions receive and return CasADi ``SX`` (column vectors for ``x``, ``u``, ``p``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property

import casadi as ca
import numpy as np
from numpy.typing import NDArray

__all__ = ["Guess", "OptimalControlProblem"]

Dynamics = Callable[[ca.SX, ca.SX, ca.SX, ca.SX], ca.SX]
Boundary = Callable[[ca.SX, ca.SX, ca.SX, ca.SX], ca.SX]

_EMPTY = np.zeros(0)


@dataclass(frozen=True)
class NodeFunctions:
    """One node's functions of ``(x, u, s, p)`` (:attr:`OptimalControlProblem.node_functions`)."""

    dynamics: ca.Function
    lagrange: ca.Function | None
    path: ca.Function | None


@dataclass(frozen=True)
class OptimalControlProblem:
    """See the module notes. Arrays are 1-D, one entry per state / control / parameter."""

    state_names: tuple[str, ...]
    control_names: tuple[str, ...]
    dynamics: Dynamics  # f(x, u, s, p) -> dx/ds
    state_lower: NDArray[np.float64]
    state_upper: NDArray[np.float64]
    control_lower: NDArray[np.float64]
    control_upper: NDArray[np.float64]
    initial_lower: NDArray[np.float64]
    initial_upper: NDArray[np.float64]
    final_lower: NDArray[np.float64]
    final_upper: NDArray[np.float64]
    s0: float
    sf_bounds: tuple[float, float]  # equal bounds: fixed final value
    state_scale: NDArray[np.float64]
    control_scale: NDArray[np.float64]
    sf_scale: float = 1.0
    objective_scale: float = 1.0
    mayer: Boundary | None = None  # Phi(x0, xf, sf, p) -> scalar
    lagrange: Dynamics | None = None  # L(x, u, s, p) -> scalar
    path: Dynamics | None = None  # c(x, u, s, p) -> vector
    path_lower: NDArray[np.float64] = field(default_factory=lambda: _EMPTY)
    path_upper: NDArray[np.float64] = field(default_factory=lambda: _EMPTY)
    # States that may not decrease from one state point to the next (the time of the
    # energy formulation: its quadrature must run forwards between the nodes too).
    increasing_states: tuple[int, ...] = ()
    boundary: Boundary | None = None  # b(x0, xf, sf, p) -> vector
    boundary_lower: NDArray[np.float64] = field(default_factory=lambda: _EMPTY)
    boundary_upper: NDArray[np.float64] = field(default_factory=lambda: _EMPTY)
    parameter_names: tuple[str, ...] = ()
    parameter_lower: NDArray[np.float64] = field(default_factory=lambda: _EMPTY)
    parameter_upper: NDArray[np.float64] = field(default_factory=lambda: _EMPTY)
    parameter_scale: NDArray[np.float64] = field(default_factory=lambda: _EMPTY)

    @property
    def nx(self) -> int:
        return len(self.state_names)

    @cached_property
    def node_functions(self) -> NodeFunctions:
        """The dynamics, Lagrange integrand and path constraints of one node as SX functions
        of ``(x, u, s, p)``, built once per problem: CasADi keeps each function's derivatives,
        so every mesh of a refinement maps the same functions and reuses them."""
        x, u = ca.SX.sym("xn", self.nx), ca.SX.sym("un", self.nu)
        s, p = ca.SX.sym("sn"), ca.SX.sym("pn", self.npar)

        def node(name: str, rule: Dynamics | None) -> ca.Function | None:
            return None if rule is None else ca.Function(name, [x, u, s, p], [rule(x, u, s, p)])

        return NodeFunctions(
            dynamics=node("f", self.dynamics),
            lagrange=node("L", self.lagrange),
            path=node("c", self.path),
        )

    @property
    def nu(self) -> int:
        return len(self.control_names)

    @property
    def npar(self) -> int:
        return len(self.parameter_names)

    @property
    def free_final(self) -> bool:
        return self.sf_bounds[0] != self.sf_bounds[1]

    def __post_init__(self) -> None:
        shapes = {
            "state_lower": (self.state_lower, self.nx),
            "state_upper": (self.state_upper, self.nx),
            "initial_lower": (self.initial_lower, self.nx),
            "initial_upper": (self.initial_upper, self.nx),
            "final_lower": (self.final_lower, self.nx),
            "final_upper": (self.final_upper, self.nx),
            "state_scale": (self.state_scale, self.nx),
            "control_lower": (self.control_lower, self.nu),
            "control_upper": (self.control_upper, self.nu),
            "control_scale": (self.control_scale, self.nu),
            "parameter_lower": (self.parameter_lower, self.npar),
            "parameter_upper": (self.parameter_upper, self.npar),
            "parameter_scale": (self.parameter_scale, self.npar),
        }
        for name, (array, size) in shapes.items():
            if np.shape(array) != (size,):
                raise ValueError(f"{name} must have shape ({size},), got {np.shape(array)}")
        if len(self.path_lower) != len(self.path_upper):
            raise ValueError("path_lower and path_upper differ in length")
        if len(self.boundary_lower) != len(self.boundary_upper):
            raise ValueError("boundary_lower and boundary_upper differ in length")
        if self.sf_bounds[0] > self.sf_bounds[1] or self.sf_bounds[0] <= self.s0:
            raise ValueError(f"need s0 < sf_lower <= sf_upper, got {self.s0}, {self.sf_bounds}")


@dataclass(frozen=True)
class Guess:
    """A trajectory sampled at increasing ``s``; interpolated linearly onto the nodes.

    ``x``: (len(s), nx); ``u``: (len(s), nu); ``sf``: final value of ``s``; ``p``: parameters.
    """

    s: NDArray[np.float64]
    x: NDArray[np.float64]
    u: NDArray[np.float64]
    sf: float
    p: NDArray[np.float64] = field(default_factory=lambda: _EMPTY)

    def at(self, s: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """States (len(s), nx) and controls (len(s), nu) at ``s``, held beyond the ends."""
        xs = np.column_stack([np.interp(s, self.s, col) for col in self.x.T])
        us = np.column_stack([np.interp(s, self.s, col) for col in self.u.T])
        return xs, us
