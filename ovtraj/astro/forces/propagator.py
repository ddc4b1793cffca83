"""Flying a state under :mod:`.dynamics`: heyoka's Taylor integrator, compiled once per
thread and :class:`~ovtraj.astro.forces.dynamics.ForceTerms` (compact mode: the expanded
EGM2008 system takes minutes to compile, the compact one seconds, and heyoka caches the
code on disk), and the same equations as a compiled function (``cfunc``) for a second
integrator (scipy's DOP853 in the tests and the benchmark) and for the term-by-term checks.

An arc stops at its end time or where the radius falls through the floor (a terminal
event), and reports the lowest radius at the integrator's steps. Every arc is bounded:
``max_arc_s`` of flight and a step count of one a second (heyoka's steps here last
minutes).
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from typing import Any

import heyoka as hy
import numpy as np

from ovtraj.astro.forces.dynamics import (
    PARAMETERS,
    ForceTerms,
    accelerations,
    equations,
    step_boundaries,
    symbols,
)
from ovtraj.units import S_PER_DAY

__all__ = ["AccelerationFunction", "Arc", "HighFidelityPropagator", "rhs_function"]


@dataclass(frozen=True)
class Arc:
    """The end of one flown arc: state (6,), time [s], whether the floor stopped it, the
    lowest radius [m] at the integrator's steps."""

    state: np.ndarray
    t: float
    stopped: bool
    lowest_radius_m: float


# heyoka reports the k-th terminal event as the outcome -(k + 1).
_FLOOR_EVENT = -1
_MIN_MEAN_STEP_S = 1.0
_STEP_ALLOWANCE = 1000


class _Cache(threading.local):
    def __init__(self) -> None:
        self.integrators: dict[tuple, Any] = {}
        self.functions: dict[tuple, Any] = {}


_CACHE = _Cache()


def _continue(_ta: Any, _sign: int) -> bool:
    """A terminal event that only ends the step where it happens."""
    return True


def _integrator(terms: ForceTerms, tol: float) -> Any:
    key = (terms, tol)
    ta = _CACHE.integrators.get(key)
    if ta is None:
        s = symbols()
        x, y, z = s.state[:3]
        # In Earth radii: an event of ~1e13 m^2 would loosen heyoka's step control (a
        # J2 day 0.14 m off at tol 1e-12; scaled, 2e-6 m).
        scale = terms.radius
        floor = hy.t_event(
            (x * x + y * y + z * z) / scale**2 - (s.par["floor_radius_m"] / scale) ** 2,
            direction=hy.event_direction.negative,
        )
        edges = [hy.t_event(boundary, callback=_continue) for boundary in step_boundaries(terms, s)]
        ta = hy.taylor_adaptive(
            equations(terms, s),
            np.zeros(6),
            tol=tol,
            t_events=[floor, *edges],
            pars=np.zeros(len(PARAMETERS)),
            compact_mode=True,
        )
        _CACHE.integrators[key] = ta
    return ta


class HighFidelityPropagator:
    """Arcs of one spacecraft under ``terms`` from an origin epoch.

    Parameters
    ----------
    terms:
        The force model.
    origin_tt_centuries, origin_day_of_year:
        TT Julian centuries since J2000 and UTC day of year of t = 0
        (:mod:`ovtraj.astro.forces.time_scales`).
    ballistic_m2_kg, radiation_m2_kg:
        The spacecraft's C_D A / m and C_R A / m.
    tol:
        Taylor tolerance (relative and absolute).
    max_arc_s:
        The longest arc [s] one call may fly.
    """

    def __init__(
        self,
        terms: ForceTerms,
        *,
        origin_tt_centuries: float,
        origin_day_of_year: float,
        ballistic_m2_kg: float,
        radiation_m2_kg: float,
        tol: float,
        max_arc_s: float,
    ) -> None:
        if not 0.0 < tol < 1e-3:
            raise ValueError(f"tol must be in (0, 1e-3), got {tol}")
        self.terms = terms
        self.tol = float(tol)
        self.max_arc_s = float(max_arc_s)
        self.parameters = np.array(
            [origin_tt_centuries, origin_day_of_year, ballistic_m2_kg, radiation_m2_kg, 0.0]
        )

    def arc(self, state: np.ndarray, t0: float, t1: float, *, floor_radius_m: float = 0.0) -> Arc:
        """Fly ``state`` from ``t0`` to ``t1`` [s] or to the floor; ``FloatingPointError``
        on a non-finite state or an integration that cannot go on."""
        if abs(t1 - t0) > self.max_arc_s:
            raise ValueError(
                f"an arc of {abs(t1 - t0):.0f} s exceeds integration.max_arc_days "
                f"({self.max_arc_s / S_PER_DAY:g} days)"
            )
        state = np.asarray(state, dtype=float)
        radius0 = float(np.linalg.norm(state[:3]))
        if t1 == t0:
            return Arc(state.copy(), float(t0), False, radius0)
        ta = _integrator(self.terms, self.tol)
        pars = self.parameters.copy()
        pars[PARAMETERS.index("floor_radius_m")] = floor_radius_m
        ta.pars[:] = pars
        ta.time = float(t0)
        ta.state[:] = state
        ta.reset_cooldowns()
        lowest = [radius0]

        def step(integrator: Any) -> bool:
            lowest[0] = min(lowest[0], float(np.linalg.norm(integrator.state[:3])))
            return True

        # heyoka's steps here are minutes long; one a second is a runaway (a bound, not a cost).
        max_steps = math.ceil(abs(t1 - t0) / _MIN_MEAN_STEP_S) + _STEP_ALLOWANCE
        outcome, *_ = ta.propagate_until(float(t1), max_steps=max_steps, callback=step)
        end = np.array(ta.state)
        if not np.all(np.isfinite(end)):
            raise FloatingPointError(f"high-fidelity arc from {t0:.1f} s: non-finite state")
        stopped = int(outcome) == _FLOOR_EVENT
        if not stopped and outcome != hy.taylor_outcome.time_limit:
            raise FloatingPointError(f"high-fidelity arc from {t0:.1f} s stopped: {outcome}")
        radius = float(np.linalg.norm(end[:3]))
        return Arc(end, float(ta.time), bool(stopped), min(lowest[0], radius))

    def grid(
        self, state: np.ndarray, t0: float, times: np.ndarray, *, ballistic_m2_kg: float
    ) -> np.ndarray:
        """States (n, 6) at the increasing ``times`` (``times[0]`` may equal ``t0``), with
        C_D A / m replaced by ``ballistic_m2_kg`` (a fit's unknown); no floor.
        ``FloatingPointError`` when the flight cannot reach the last time."""
        times = np.asarray(times, dtype=float)
        if times[-1] - t0 > self.max_arc_s:
            raise ValueError(f"a grid of {times[-1] - t0:.0f} s exceeds the longest arc")
        ta = _integrator(self.terms, self.tol)
        pars = self.parameters.copy()
        pars[PARAMETERS.index("ballistic_m2_kg")] = ballistic_m2_kg
        ta.pars[:] = pars
        ta.time = float(t0)
        ta.state[:] = np.asarray(state, dtype=float)
        ta.reset_cooldowns()
        max_steps = math.ceil((times[-1] - t0) / _MIN_MEAN_STEP_S) + _STEP_ALLOWANCE
        outcome, *_, out = ta.propagate_grid(times, max_steps=max_steps)
        if outcome != hy.taylor_outcome.time_limit or not np.all(np.isfinite(out)):
            raise FloatingPointError(f"high-fidelity grid from {t0:.1f} s stopped: {outcome}")
        return np.array(out)


class AccelerationFunction:
    """The terms' accelerations compiled as a function of (state, time): for the checks
    against independent evaluations and for a second integrator.

    ``__call__(states (n, 6), t (n,), parameters (5,))`` returns each term's (n, 3) and
    their sum under ``"total"``.
    """

    def __init__(self, terms: ForceTerms) -> None:
        key = ("accelerations", terms)
        cached = _CACHE.functions.get(key)
        if cached is None:
            s = symbols()
            parts = accelerations(terms, s)
            names = list(parts)  # the order of ovtraj.astro.forces.terms.FORCE_TERMS
            outputs = [c for name in names for c in parts[name]]
            cf = hy.cfunc(outputs, list(s.state), compact_mode=True)
            cached = (names, cf)
            _CACHE.functions[key] = cached
        self.names, self._cf = cached

    def __call__(
        self, states: np.ndarray, t: np.ndarray, parameters: np.ndarray
    ) -> dict[str, np.ndarray]:
        states = np.atleast_2d(np.asarray(states, dtype=float))
        n = len(states)
        t = np.broadcast_to(np.asarray(t, dtype=float), (n,))
        parameters = np.asarray(parameters, dtype=float)[: self._cf.nparams]
        pars = np.tile(parameters[:, None], (1, n))
        values = np.asarray(self._cf(states.T.copy(), pars=pars, time=t.copy())).T
        out = {name: values[:, 3 * k : 3 * k + 3] for k, name in enumerate(self.names)}
        out["total"] = sum(out.values())
        return out


def rhs_function(terms: ForceTerms, parameters: np.ndarray) -> Any:
    """``f(t, y)``, the state's derivative under ``terms`` (for scipy's ``solve_ivp``):
    the same compiled equations as the Taylor integrator, one state at a time."""
    key = ("rhs", terms)
    cf = _CACHE.functions.get(key)
    if cf is None:
        s = symbols()
        cf = hy.cfunc([d for _, d in equations(terms, s)], list(s.state), compact_mode=True)
        _CACHE.functions[key] = cf
    pars = np.asarray(parameters, dtype=float)[: cf.nparams].copy()
    out = np.empty(6)

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        cf(y, pars=pars, time=float(t), outputs=out)
        return out.copy()

    return rhs
