"""Pseudospectral transcription of an :class:`OptimalControlProblem` into a CasADi NLP.

The interval ``[s0, sf]`` is split into ``segments`` equal segments, each mapped to
``tau`` in [-1, 1] by ``s = s_a + (tau + 1) (s_b - s_a) / 2`` (seed eq. 17). In each
segment the state is the Lagrange polynomial through the scheme's support points and the
dynamics hold at the collocation points (seed eq. 22, Benson et al., JGCD 29(6), 2006,
eqs. 19-24; LGR: Garg et al., Automatica 46(11), 2010, eqs. 29-33)::

    sum_i D[k, i] X_i - (s_b - s_a) / 2 f(X_k, U_k, s_k, p) = 0        (k = 1 .. n)
    LG only:  X_end - X_start - (s_b - s_a) / 2 sum_k w_k f_k = 0         (seed eq. 23)

The last state of a segment is the first of the next (continuity by construction);
controls live at the collocation points only and may jump between segments. The
Lagrange term is Gauss (or Radau) quadrature, ``(s_b - s_a) / 2 sum_k w_k L_k`` (seed
eq. 24); path constraints hold at the collocation points (seed eq. 26).

NLP variables are the physical values divided by the problem's scales; each defect is
divided by its state's scale and the objective by ``objective_scale``, so that IPOPT
sees numbers of order one.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from ovtraj.studies.optimal_entry.collocation import (
    CollocationScheme,
    SchemeKind,
    collocation_scheme,
)
from ovtraj.studies.optimal_entry.ocp import Guess, OptimalControlProblem

__all__ = ["DiscreteSolution", "Transcription", "transcribe"]


@dataclass(frozen=True)
class DiscreteSolution:
    """The NLP's answer in physical units.

    ``s``: (M,) independent variable at every state point; ``x``: (M, nx);
    ``s_colloc``: (K,) at the collocation points; ``x_colloc``: (K, nx); ``u``: (K, nu);
    ``sf`` and ``p``: final value of ``s`` and the parameters.
    """

    s: NDArray[np.float64]
    x: NDArray[np.float64]
    s_colloc: NDArray[np.float64]
    x_colloc: NDArray[np.float64]
    u: NDArray[np.float64]
    sf: float
    p: NDArray[np.float64]
    transcription: Transcription

    def integral(self, values: NDArray[np.float64]) -> float:
        """Quadrature over the phase of ``values`` given at the collocation points."""
        return self.transcription.integral(values, self.sf)

    def cumulative(self, values: NDArray[np.float64]) -> NDArray[np.float64]:
        """``integral_{s0}^{s} g ds`` at every state point, ``g`` given at the collocation points.

        Exact for the collocation polynomial (the integration matrix), so a quantity
        integrated here equals what a state with rate ``g`` would have been.
        """
        return self.transcription.cumulative(values, self.sf)


@dataclass
class Transcription:
    """The NLP of one problem (see the module notes) and the maps to and from it."""

    ocp: OptimalControlProblem
    scheme: CollocationScheme
    segments: int
    nlp: dict[str, ca.MX]
    blocks: list[tuple[ca.MX | None, ca.MX | None]]  # g's rows: linear and nonlinear terms
    lbx: NDArray[np.float64]
    ubx: NDArray[np.float64]
    lbg: NDArray[np.float64]
    ubg: NDArray[np.float64]
    point_fraction: NDArray[np.float64]  # position of every state point in [0, 1]
    colloc_fraction: NDArray[np.float64]
    colloc_point: NDArray[np.intp]  # the state point of every collocation point
    segment_points: list[NDArray[np.intp]]  # support (+ LG end) of each segment
    segment_edges: NDArray[np.float64]
    _nxvar: int
    _nuvar: int

    def jacobian(self) -> ca.Function:
        """``(x, p) -> (g, dg/dx)`` for IPOPT, block by block: a constant sparse matrix for
        the linear terms plus CasADi's Jacobian of the nonlinear ones.

        A segment's differentiation matrix couples all its state points, so the Jacobian
        of the whole of ``g`` needs a forward sweep per state-point variable through every
        mapped node (182 on the seed's 1 x 30 mesh). The dynamics and path terms alone are
        one block per collocation point (about a dozen sweeps); the LG end quadrature's
        few rows go by reverse sweeps; the linear terms' Jacobian is evaluated once.
        """
        x = self.nlp["x"]
        rows = []
        for linear, nonlinear in self.blocks:
            jac = None
            if linear is not None:
                constant = ca.Function("linear_jacobian", [x], [ca.jacobian(linear, x)])
                jac = ca.DM(constant(np.zeros(x.shape[0])))
            if nonlinear is not None:
                dynamic = ca.jacobian(nonlinear, x)
                jac = dynamic if jac is None else jac + dynamic
            rows.append(jac)
        p = ca.MX.sym("p", 0)
        return ca.Function(
            "nlp_jac_g", [x, p], [self.nlp["g"], ca.vertcat(*rows)], ["x", "p"], ["g", "jac_g_x"]
        )

    @property
    def n_points(self) -> int:
        return len(self.point_fraction)

    @property
    def n_colloc(self) -> int:
        return len(self.colloc_fraction)

    def _s(self, fraction: NDArray[np.float64], sf: float) -> NDArray[np.float64]:
        return self.ocp.s0 + fraction * (sf - self.ocp.s0)

    def initial_point(self, guess: Guess) -> NDArray[np.float64]:
        """The scaled NLP vector of a guess, clipped into the variable bounds."""
        ocp = self.ocp
        sf = guess.sf if ocp.free_final else ocp.sf_bounds[0]
        xs, _ = guess.at(self._s(self.point_fraction, sf))
        _, us = guess.at(self._s(self.colloc_fraction, sf))
        parts = [
            (xs / ocp.state_scale).T.ravel(order="F"),
            (us / ocp.control_scale).T.ravel(order="F"),
        ]
        if ocp.free_final:
            parts.append(np.array([sf / ocp.sf_scale]))
        if ocp.npar:
            parts.append(np.asarray(guess.p, dtype=float) / ocp.parameter_scale)
        x0 = np.concatenate(parts)
        return np.clip(x0, self.lbx, self.ubx)

    def unpack(self, w: NDArray[np.float64]) -> DiscreteSolution:
        ocp = self.ocp
        w = np.asarray(w, dtype=float).ravel()
        nx, nu = ocp.nx, ocp.nu
        x = w[: self._nxvar].reshape(self.n_points, nx) * ocp.state_scale
        u = w[self._nxvar : self._nxvar + self._nuvar].reshape(self.n_colloc, nu)
        u = u * ocp.control_scale
        k = self._nxvar + self._nuvar
        if ocp.free_final:
            sf = float(w[k] * ocp.sf_scale)
            k += 1
        else:
            sf = ocp.sf_bounds[0]
        p = w[k : k + ocp.npar] * ocp.parameter_scale
        return DiscreteSolution(
            s=self._s(self.point_fraction, sf),
            x=x,
            s_colloc=self._s(self.colloc_fraction, sf),
            x_colloc=x[self.colloc_point],
            u=u,
            sf=sf,
            p=p,
            transcription=self,
        )

    def integral(self, values: NDArray[np.float64], sf: float) -> float:
        n = self.scheme.n
        total = 0.0
        for k in range(self.segments):
            half = 0.5 * (sf - self.ocp.s0) * (self.segment_edges[k + 1] - self.segment_edges[k])
            total += half * float(self.scheme.weights @ values[k * n : (k + 1) * n])
        return total

    def cumulative(self, values: NDArray[np.float64], sf: float) -> NDArray[np.float64]:
        n = self.scheme.n
        a = self.scheme.integration_matrix()
        out = np.zeros(self.n_points)
        for k, points in enumerate(self.segment_points):
            half = 0.5 * (sf - self.ocp.s0) * (self.segment_edges[k + 1] - self.segment_edges[k])
            g = half * np.asarray(values[k * n : (k + 1) * n], dtype=float)
            start = out[points[0]]
            out[points[1 : n + 1]] = start + a @ g
            if self.scheme.end_by_quadrature:
                out[points[-1]] = start + float(self.scheme.weights @ g)
        return out


def _layout(
    scheme: CollocationScheme, edges: NDArray
) -> tuple[NDArray, NDArray, NDArray, list[NDArray], list[NDArray], NDArray]:
    """Positions in [0, 1] of the state and collocation points, and their indices."""
    segments = len(edges) - 1
    n = scheme.n
    fractions = [0.0]
    colloc_fraction: list[float] = []
    colloc_point: list[int] = []
    support_idx: list[NDArray] = []
    segment_points: list[NDArray] = []
    for k in range(segments):
        a, b = edges[k], edges[k + 1]

        def place(tau: NDArray, a: float = a, b: float = b) -> NDArray:
            return a + 0.5 * (tau + 1.0) * (b - a)

        start = len(fractions) - 1
        # LG: the collocation points (the end follows); LGR: the Radau points and +1.
        first_new = len(fractions)
        fractions.extend(place(scheme.support[1:]).tolist())
        if scheme.end_by_quadrature:
            fractions.append(b)
        support = np.array([start, *range(first_new, first_new + n)], dtype=np.intp)
        support_idx.append(support)
        segment_points.append(np.arange(start, len(fractions), dtype=np.intp))
        colloc_point.extend(support[scheme.colloc_index].tolist())
        colloc_fraction.extend(place(scheme.collocation).tolist())
    fractions[-1] = 1.0
    return (
        np.array(fractions),
        np.array(colloc_fraction),
        np.array(colloc_point, dtype=np.intp),
        support_idx,
        segment_points,
        edges,
    )


def transcribe(
    ocp: OptimalControlProblem,
    kind: SchemeKind,
    nodes: int,
    segments: int = 1,
    edges: NDArray[np.float64] | None = None,
) -> Transcription:
    """Build the NLP of ``ocp`` with ``segments`` segments of ``nodes`` collocation points.

    ``edges``: the segment boundaries as fractions of the interval (increasing from 0 to
    1; a refined mesh), instead of ``segments`` equal segments.
    """
    if edges is None:
        edges = np.linspace(0.0, 1.0, segments + 1)
    edges = np.asarray(edges, dtype=float)
    segments = len(edges) - 1
    if segments < 1 or nodes < 1:
        raise ValueError(f"need at least one segment and one node, got {segments}, {nodes}")
    if edges[0] != 0.0 or edges[-1] != 1.0 or np.any(np.diff(edges) <= 0.0):
        raise ValueError("segment edges must increase from 0 to 1")
    scheme = collocation_scheme(kind, nodes)
    point_fraction, colloc_fraction, colloc_point, support_idx, segment_points, edges = _layout(
        scheme, edges
    )
    m, kc = len(point_fraction), len(colloc_fraction)
    v = _variables(ocp, m, colloc_fraction, colloc_point)
    blocks, objective = _collocation(ocp, scheme, edges, support_idx, segment_points, v)
    blocks += _path_and_boundary(ocp, v)
    constraints, lbg, ubg = _stacked(blocks)
    if ocp.mayer is not None:
        objective += ocp.mayer(v.x_first, v.x_last, v.sf, v.p)
    variables, lbx, ubx = _variable_bounds(ocp, v, m, kc)
    nlp = {
        "x": ca.vertcat(*variables),
        "f": objective / ocp.objective_scale,
        "g": ca.vertcat(*constraints),
    }
    return Transcription(
        ocp=ocp,
        scheme=scheme,
        segments=segments,
        nlp=nlp,
        blocks=[(linear, nonlinear) for linear, nonlinear, _, _ in blocks],
        lbx=np.concatenate(lbx),
        ubx=np.concatenate(ubx),
        lbg=np.concatenate(lbg),
        ubg=np.concatenate(ubg),
        point_fraction=point_fraction,
        colloc_fraction=colloc_fraction,
        colloc_point=colloc_point,
        segment_points=segment_points,
        segment_edges=edges,
        _nxvar=ocp.nx * m,
        _nuvar=ocp.nu * kc,
    )


# A block of g's rows: (linear terms, nonlinear terms, lower bounds, upper bounds). The
# linear terms (differentiation matrices, end-point differences, monotonicity) have a
# constant Jacobian, evaluated once (Transcription.jacobian).
_Block = tuple[ca.MX | None, ca.MX | None, NDArray, NDArray]


@dataclass(frozen=True)
class _Variables:
    """The NLP's variables (scaled) and the physical values they stand for."""

    xs: ca.MX  # scaled states, one column per state point
    us: ca.MX  # scaled controls, one column per collocation point
    sf_var: ca.MX | None  # the scaled final value of s, when free
    ps: ca.MX  # scaled parameters
    x: ca.MX
    u: ca.MX
    p: ca.MX
    sf: ca.MX
    span: ca.MX  # sf - s0
    s_colloc: ca.MX
    x_colloc: ca.MX  # the states at the collocation points
    x_first: ca.MX
    x_last: ca.MX


def _variables(
    ocp: OptimalControlProblem, m: int, colloc_fraction: NDArray, colloc_point: NDArray
) -> _Variables:
    # MX variables around per-node SX functions: derivatives are generated for one node
    # and mapped, which builds the NLP in a fraction of the time of one flat SX graph.
    kc = len(colloc_fraction)
    xs = ca.MX.sym("x", ocp.nx, m)
    us = ca.MX.sym("u", ocp.nu, kc)
    sf_var = ca.MX.sym("sf") if ocp.free_final else None
    ps = ca.MX.sym("p", ocp.npar)
    x_scale = ca.DM(ocp.state_scale)
    x = xs * ca.repmat(x_scale, 1, m)
    u = us * ca.repmat(ca.DM(ocp.control_scale), 1, kc)
    p = ps * ca.DM(ocp.parameter_scale) if ocp.npar else ps
    sf = sf_var * ocp.sf_scale if sf_var is not None else ca.MX(ocp.sf_bounds[0])
    span = sf - ocp.s0
    s_colloc = ocp.s0 + ca.DM(colloc_fraction).T * span
    return _Variables(
        xs=xs,
        us=us,
        sf_var=sf_var,
        ps=ps,
        x=x,
        u=u,
        p=p,
        sf=sf,
        span=span,
        s_colloc=s_colloc,
        x_colloc=x[:, colloc_point.tolist()],
        x_first=x[:, 0],
        x_last=x[:, m - 1],
    )


def _collocation(
    ocp: OptimalControlProblem,
    scheme: CollocationScheme,
    edges: NDArray,
    support_idx: list[NDArray],
    segment_points: list[NDArray],
    v: _Variables,
) -> tuple[list[_Block], ca.MX]:
    """The defect constraints of every segment (and, LG, its end by quadrature), and the
    Lagrange term's quadrature (module notes)."""
    nx, segments, n, kc = ocp.nx, len(edges) - 1, scheme.n, v.us.shape[1]
    # One symbolic evaluation per node; map() keeps the expression graph compact. The
    # node functions are the problem's, so every mesh of a refinement reuses their
    # derivatives.
    node = ocp.node_functions
    f_all = node.dynamics.map(kc)(v.x_colloc, v.u, v.s_colloc, ca.repmat(v.p, 1, kc))
    d = ca.DM(scheme.d)
    w = ca.DM(scheme.weights)
    inv_scale = ca.DM(1.0 / ocp.state_scale)
    objective = ca.MX(0.0)
    if node.lagrange is not None:
        l_all = node.lagrange.map(kc)(v.x_colloc, v.u, v.s_colloc, ca.repmat(v.p, 1, kc))
    defect_linear, defect_dynamics, end_linear, end_dynamics = [], [], [], []
    for k in range(segments):
        half = 0.5 * v.span * float(edges[k + 1] - edges[k])
        cols = list(range(k * n, (k + 1) * n))
        f_k = f_all[:, cols] * ca.repmat(inv_scale, 1, n)
        defect_linear.append(ca.vec(ca.mtimes(v.xs[:, support_idx[k].tolist()], d.T)))
        defect_dynamics.append(ca.vec(-half * f_k))
        if scheme.end_by_quadrature:
            end = int(segment_points[k][-1])
            start = int(support_idx[k][0])
            end_linear.append(v.xs[:, end] - v.xs[:, start])
            end_dynamics.append(-half * ca.mtimes(f_k, w))
        if node.lagrange is not None:
            objective += half * ca.mtimes(l_all[:, cols], w)
    zeros = np.zeros(nx * kc)
    blocks: list[_Block] = [
        (ca.vertcat(*defect_linear), ca.vertcat(*defect_dynamics), zeros, zeros)
    ]
    if end_linear:
        zeros = np.zeros(nx * segments)
        blocks.append((ca.vertcat(*end_linear), ca.vertcat(*end_dynamics), zeros, zeros))
    return blocks, objective


def _path_and_boundary(ocp: OptimalControlProblem, v: _Variables) -> list[_Block]:
    """The states that may not decrease, the path constraints at the collocation points
    and the boundary constraints."""
    m, kc = v.xs.shape[1], v.us.shape[1]
    blocks: list[_Block] = []
    for j in ocp.increasing_states:
        # State points are in increasing s: consecutive differences of x_j >= 0.
        blocks.append(
            (ca.vec(v.xs[j, 1:] - v.xs[j, : m - 1]), None, np.zeros(m - 1), np.full(m - 1, np.inf))
        )
    node = ocp.node_functions
    if node.path is not None:
        c_all = node.path.map(kc)(v.x_colloc, v.u, v.s_colloc, ca.repmat(v.p, 1, kc))
        blocks.append(
            (None, ca.vec(c_all), np.tile(ocp.path_lower, kc), np.tile(ocp.path_upper, kc))
        )
    if ocp.boundary is not None:
        blocks.append(
            (
                None,
                ocp.boundary(v.x_first, v.x_last, v.sf, v.p),
                np.asarray(ocp.boundary_lower, dtype=float),
                np.asarray(ocp.boundary_upper, dtype=float),
            )
        )
    return blocks


def _stacked(blocks: list[_Block]) -> tuple[list[ca.MX], list[NDArray], list[NDArray]]:
    """Each block's rows (its linear plus its nonlinear terms) and their bounds."""
    constraints: list[ca.MX] = []
    lbg: list[NDArray] = []
    ubg: list[NDArray] = []
    for linear, nonlinear, lower_g, upper_g in blocks:
        parts = [term for term in (linear, nonlinear) if term is not None]
        constraints.append(parts[0] + parts[1] if len(parts) == 2 else parts[0])
        lbg.append(lower_g)
        ubg.append(upper_g)
    return constraints, lbg, ubg


def _variable_bounds(
    ocp: OptimalControlProblem, v: _Variables, m: int, kc: int
) -> tuple[list[ca.MX], list[NDArray], list[NDArray]]:
    """The NLP's variables in order and their (scaled) bounds: states everywhere,
    tightened at the two ends; controls; the final value of s; the parameters."""
    lower = np.tile(ocp.state_lower, (m, 1))
    upper = np.tile(ocp.state_upper, (m, 1))
    lower[0] = np.maximum(lower[0], ocp.initial_lower)
    upper[0] = np.minimum(upper[0], ocp.initial_upper)
    lower[-1] = np.maximum(lower[-1], ocp.final_lower)
    upper[-1] = np.minimum(upper[-1], ocp.final_upper)
    lbx = [(lower / ocp.state_scale).ravel(), np.tile(ocp.control_lower / ocp.control_scale, kc)]
    ubx = [(upper / ocp.state_scale).ravel(), np.tile(ocp.control_upper / ocp.control_scale, kc)]
    variables = [ca.vec(v.xs), ca.vec(v.us)]
    if v.sf_var is not None:
        variables.append(v.sf_var)
        lbx.append(np.array([ocp.sf_bounds[0] / ocp.sf_scale]))
        ubx.append(np.array([ocp.sf_bounds[1] / ocp.sf_scale]))
    if ocp.npar:
        variables.append(v.ps)
        lbx.append(ocp.parameter_lower / ocp.parameter_scale)
        ubx.append(ocp.parameter_upper / ocp.parameter_scale)
    return variables, lbx, ubx
