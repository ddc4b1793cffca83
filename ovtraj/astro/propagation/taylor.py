"""Orbit propagation with heyoka's Taylor integrator (two-body + J2, with events).

Why heyoka: it compiles the equations of motion to machine code once and then
integrates a day of LEO motion in a fraction of a millisecond, with event
detection by polynomial root finding inside each step and dense output from the
Taylor series at no extra cost (Biscani & Izzo, MNRAS 2021).

Compilation is the expensive part (0.3-1 s), so integrators are built once per
thread and per *shape* of problem (tolerance, event kinds) and reused; every
figure that can change between calls (mu, R, J2, the Earth rotation angle, the
event values) is a runtime parameter. Setting J2 to zero gives the two-body
problem on the same compiled code. Integrators are kept per thread because a
heyoka integrator is mutable state and must not be shared between threads.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import heyoka as hy
import numpy as np

from ovtraj.astro.constants import EarthModel
from ovtraj.astro.propagation.events import Event, EventContext
from ovtraj.astro.propagation.gravity import two_body_j2_acceleration

Status = Literal["time_limit", "terminal_event", "error"]

_STATE_NAMES = ("x", "y", "z", "vx", "vy", "vz")
# Runtime parameters shared by every integrator, in this order.
_SHARED_PARAMS = ("mu", "radius", "j2", "omega")
# A root found this close to the start time is the initial point sitting on the
# event surface, not a crossing.
_START_ROOT_WINDOW_S = 1e-6

_DIRECTIONS = {
    "any": hy.event_direction.any,
    "positive": hy.event_direction.positive,
    "negative": hy.event_direction.negative,
}


@dataclass(frozen=True)
class EventHit:
    """One root of an event function: which event, when, and the state then."""

    event_index: int
    t: float
    state: np.ndarray


@dataclass
class PropagationResult:
    """Outcome of :meth:`OrbitPropagator.propagate`.

    ``t`` and ``state`` are where the integration ended (the requested end time or
    the terminal event). ``hits`` lists every accepted event root in time order.
    ``dense(t)`` evaluates the trajectory anywhere in [t0, t] when dense output
    was requested.
    """

    t0: float
    t: float
    state: np.ndarray
    status: Status
    terminal_event: int | None = None
    hits: list[EventHit] = field(default_factory=list)
    message: str = ""
    _dense: Any = None

    @property
    def ok(self) -> bool:
        return self.status != "error"

    def dense(self, t: float | np.ndarray) -> np.ndarray:
        """States (..., 6) at times ``t`` inside the propagated interval."""
        if self._dense is None:
            raise ValueError("propagate(..., dense=True) is needed for dense output")
        t_arr = np.atleast_1d(np.asarray(t, dtype=float))
        lo, hi = min(self.t0, self.t), max(self.t0, self.t)
        if np.any(t_arr < lo - 1e-9) or np.any(t_arr > hi + 1e-9):
            raise ValueError(f"t must lie in [{lo}, {hi}] s for this trajectory")
        # heyoka returns a view of its internal buffer: copy before the next call.
        out = np.array(self._dense(np.clip(t_arr, lo, hi)), dtype=float)
        out = out.reshape(len(t_arr), -1)[:, :6]
        return out[0] if np.ndim(t) == 0 else out

    def state_at(self, t: float) -> np.ndarray:
        """State (6,) at one time, clipped to the propagated interval (hot-path lookup)."""
        if self._dense is None:
            raise ValueError("propagate(..., dense=True) is needed for dense output")
        lo, hi = min(self.t0, self.t), max(self.t0, self.t)
        return np.array(self._dense(min(max(float(t), lo), hi))[:6])

    def states_at(self, t: np.ndarray) -> np.ndarray:
        """:meth:`state_at` of several times (m,): states (m, 6), one dense-output call."""
        if self._dense is None:
            raise ValueError("propagate(..., dense=True) is needed for dense output")
        lo, hi = min(self.t0, self.t), max(self.t0, self.t)
        t_arr = np.clip(np.asarray(t, dtype=float).reshape(-1), lo, hi)
        return np.array(self._dense(t_arr), dtype=float).reshape(len(t_arr), -1)[:, :6]


@dataclass(frozen=True)
class _Stationary:
    """The dense output of a zero-length propagation: its one state at any time asked."""

    state: np.ndarray

    def __call__(self, t: float | np.ndarray) -> np.ndarray:
        return np.tile(self.state, np.size(t)) if np.ndim(t) else self.state.copy()


def _symbols() -> tuple[dict[str, Any], dict[str, Any]]:
    state = dict(zip(_STATE_NAMES, hy.make_vars(*_STATE_NAMES), strict=True))
    shared = {name: hy.par[i] for i, name in enumerate(_SHARED_PARAMS)}
    shared.update(time=hy.time, sqrt=hy.sqrt, sin=hy.sin, cos=hy.cos)
    return state, shared


def _equations(state: dict[str, Any], shared: dict[str, Any]) -> list[tuple[Any, Any]]:
    ax, ay, az = two_body_j2_acceleration(
        state["x"],
        state["y"],
        state["z"],
        mu=shared["mu"],
        radius=shared["radius"],
        j2=shared["j2"],
        sqrt=hy.sqrt,
    )
    return [
        (state["x"], state["vx"]),
        (state["y"], state["vy"]),
        (state["z"], state["vz"]),
        (state["vx"], ax),
        (state["vy"], ay),
        (state["vz"], az),
    ]


class _EventIntegrator:
    """A compiled integrator for one tolerance and one tuple of event signatures."""

    def __init__(self, tol: float, prototypes: Sequence[Event]) -> None:
        state, shared = _symbols()
        self.terminal_slots: list[int] = []  # heyoka terminal index -> event index
        self.calls: dict[str, Any] = {}
        t_events, nt_events = [], []
        next_par = len(_SHARED_PARAMS)
        self.par_slices: list[slice] = []
        for index, proto in enumerate(prototypes):
            n_par = len(proto.parameters(EventContext(1.0, 0.0, 0.0)))
            par = [hy.par[next_par + k] for k in range(n_par)]
            self.par_slices.append(slice(next_par, next_par + n_par))
            next_par += n_par
            expr = proto.expression(state, par, shared)
            direction = _DIRECTIONS[proto.direction]
            if proto.terminal:
                self.terminal_slots.append(index)
                t_events.append(
                    hy.t_event(expr, callback=self._terminal_callback(index), direction=direction)
                )
            else:
                nt_events.append(
                    hy.nt_event(expr, self._nonterminal_callback(index), direction=direction)
                )
        self.n_pars = next_par
        self.ta = hy.taylor_adaptive(
            _equations(state, shared),
            np.zeros(6),
            tol=tol,
            t_events=t_events,
            nt_events=nt_events,
            compact_mode=False,
        )

    def _accept(self, index: int, t: float, st: np.ndarray) -> bool:
        if abs(t - self.calls["t0"]) <= _START_ROOT_WINDOW_S:
            return False
        return self.calls["events"][index].accepts(t, st, self.calls["ctx"])

    def _terminal_callback(self, index: int) -> Callable[[Any, int], bool]:
        def callback(ta: Any, _sign: int) -> bool:
            t, st = float(ta.time), np.array(ta.state[:6])
            if not self._accept(index, t, st):
                return True  # keep integrating
            self.calls["hits"].append(EventHit(index, t, st))
            return False

        return callback

    def _nonterminal_callback(self, index: int) -> Callable[[Any, float, int], None]:
        def callback(ta: Any, t: float, _sign: int) -> None:
            st = np.array(ta.update_d_output(t)[:6])
            if self._accept(index, float(t), st):
                self.calls["hits"].append(EventHit(index, float(t), st))

        return callback


class _Cache(threading.local):
    def __init__(self) -> None:
        self.event_integrators: dict[tuple, _EventIntegrator] = {}
        self.batch: dict[float, Any] = {}
        self.variational: dict[float, Any] = {}
        self.variational_batch: dict[float, Any] = {}


_CACHE = _Cache()


def _event_integrator(tol: float, events: Sequence[Event]) -> _EventIntegrator:
    key = (tol, tuple(e.signature() for e in events))
    integrator = _CACHE.event_integrators.get(key)
    if integrator is None:
        integrator = _EventIntegrator(tol, events)
        _CACHE.event_integrators[key] = integrator
    return integrator


class OrbitPropagator:
    """Two-body + J2 propagation of Cartesian ECI states (m, m/s; t in s from the epoch).

    Parameters
    ----------
    earth:
        Earth model (mu, equatorial radius, J2, rotation rate).
    tol:
        Relative and absolute tolerance of the Taylor integrator.
    j2:
        Include the J2 term (False gives the two-body problem).
    earth_angle0_rad:
        Earth rotation angle (GMST) at t = 0, for ground-track events.
    """

    def __init__(
        self,
        earth: EarthModel,
        *,
        tol: float,
        j2: bool = True,
        earth_angle0_rad: float = 0.0,
    ) -> None:
        if not 0.0 < tol < 1e-3:
            raise ValueError(f"tol must be in (0, 1e-3), got {tol}")
        self.earth = earth
        self.tol = float(tol)
        self.j2 = bool(j2)
        self.context = EventContext(
            earth.equatorial_radius_m, float(earth_angle0_rad), earth.rotation_rate_rad_s
        )

    @property
    def shared_parameters(self) -> list[float]:
        e = self.earth
        return [e.mu_m3_s2, e.equatorial_radius_m, e.j2 if self.j2 else 0.0, e.rotation_rate_rad_s]

    def propagate(
        self,
        state0: np.ndarray,
        t0: float,
        t1: float,
        *,
        events: Sequence[Event] = (),
        dense: bool = False,
    ) -> PropagationResult:
        """Propagate ``state0`` from ``t0`` to ``t1`` or to the first terminal event.

        Never raises on numerical failure: a non-finite state comes back with
        ``status == "error"`` and a message, so batch callers can record it.
        """
        if dense and t1 == t0 and not events:
            # Nothing to integrate: the state itself, without heyoka's continuous-output
            # object (~1 ms), e.g. a transfer that burns at its start.
            state = np.array(state0, dtype=float).reshape(6)
            return PropagationResult(
                float(t0), float(t0), state, "time_limit", _dense=_Stationary(state)
            )
        integrator = _event_integrator(self.tol, events)
        ta = integrator.ta
        pars = np.zeros(integrator.n_pars)
        pars[: len(_SHARED_PARAMS)] = self.shared_parameters
        for ev, sl in zip(events, integrator.par_slices, strict=True):
            pars[sl] = ev.parameters(self.context)
        # heyoka sizes the parameter vector by the highest index the system uses.
        ta.pars[:] = pars[: len(ta.pars)]
        ta.time = float(t0)
        ta.state[:] = np.asarray(state0, dtype=float)
        if events:
            ta.reset_cooldowns()
        integrator.calls = {
            "t0": float(t0),
            "events": list(events),
            "ctx": self.context,
            "hits": [],
        }
        outcome, *_, c_output, _ = ta.propagate_until(float(t1), c_output=dense)
        hits = sorted(integrator.calls["hits"], key=lambda h: h.t * np.sign(t1 - t0 or 1.0))
        result = PropagationResult(
            t0=float(t0),
            t=float(ta.time),
            state=np.array(ta.state[:6]),
            status="time_limit",
            hits=hits,
            _dense=c_output,
        )
        code = int(outcome)
        if outcome == hy.taylor_outcome.time_limit:
            return result
        if -len(integrator.terminal_slots) <= code < 0:
            result.status = "terminal_event"
            result.terminal_event = integrator.terminal_slots[-code - 1]
            return result
        result.status = "error"
        result.message = f"integration stopped at t = {ta.time:.3f} s: {outcome}"
        return result

    def propagate_grid(self, state0: np.ndarray, t0: float, times: np.ndarray) -> np.ndarray:
        """States (n, 6) at monotonic ``times`` (the first may equal ``t0``).

        heyoka's own grid output (its dense output inside each step): no continuous-output
        object, whose ~1 ms fixed cost is most of a short coast's. With
        ``times[0] == t0`` the states equal ``propagate(..., dense=True).dense(times)``.
        """
        times = np.asarray(times, dtype=float)
        ta = _event_integrator(self.tol, ()).ta
        ta.pars[:] = self.shared_parameters[: len(ta.pars)]
        ta.time = float(t0)
        ta.state[:] = np.asarray(state0, dtype=float)
        outcome = hy.taylor_outcome.time_limit
        if times[0] != t0:
            outcome, *_ = ta.propagate_until(float(times[0]))
        if outcome == hy.taylor_outcome.time_limit:
            outcome, *_, states = ta.propagate_grid(times)
        if outcome != hy.taylor_outcome.time_limit:
            raise RuntimeError(f"integration stopped at t = {ta.time:.3f} s: {outcome}")
        return np.array(states, dtype=float)[:, :6]

    def propagate_batch(
        self, states0: np.ndarray, t0: float | np.ndarray, t1: float | np.ndarray
    ) -> np.ndarray:
        """Propagate many states at once (SIMD batch mode); returns (n, 6).

        Each row may have its own start and end time. Rows whose integration fails
        come back as NaN and nothing else; callers check ``np.isfinite``.
        """
        states0 = np.atleast_2d(np.asarray(states0, dtype=float))
        n = len(states0)
        t0 = np.broadcast_to(np.asarray(t0, dtype=float), (n,))
        t1 = np.broadcast_to(np.asarray(t1, dtype=float), (n,))
        ta = self._batch_integrator()
        size = ta.batch_size
        out = np.empty_like(states0)
        for start in range(0, n, size):
            rows = slice(start, min(start + size, n))
            k = rows.stop - rows.start
            # Pad the last chunk by repeating its first row.
            pad = np.r_[np.arange(rows.start, rows.stop), np.full(size - k, rows.start)]
            ta.set_time(t0[pad])
            ta.state[:] = states0[pad].T
            n_par = ta.pars.shape[0]
            ta.pars[:] = np.tile(np.asarray(self.shared_parameters[:n_par])[:, None], (1, size))
            ta.propagate_until(t1[pad])
            outcomes = [o for o, *_ in ta.propagate_res]
            chunk = np.array(ta.state).T[:k]
            failed = [i for i, o in enumerate(outcomes[:k]) if o != hy.taylor_outcome.time_limit]
            chunk[failed] = np.nan
            out[rows] = chunk
        return out

    def propagate_with_stm(
        self, state0: np.ndarray, t0: float, t1: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Final state (6,) and state-transition matrix d x(t1) / d x(t0) (6, 6).

        Exact first-order variational equations, integrated with the state.
        """
        ta = self._variational_integrator()
        ta.time = float(t0)
        ta.state[:] = np.r_[np.asarray(state0, dtype=float), np.eye(6).ravel()]
        ta.pars[:] = self.shared_parameters[: len(ta.pars)]
        outcome, *_ = ta.propagate_until(float(t1))
        if outcome != hy.taylor_outcome.time_limit:
            raise FloatingPointError(f"variational propagation failed: {outcome}")
        s = np.array(ta.state)
        return s[:6], s[6:].reshape(6, 6)

    def propagate_with_stm_batch(
        self, states0: np.ndarray, t0: np.ndarray, t1: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`propagate_with_stm` of many states at once: (n, 6) and (n, 6, 6).

        heyoka's batch mode (SIMD lanes, each with its own steps and times), compiled
        without compact mode: the lanes agree with the scalar integrator to the
        integration's tolerance (not to the bit), and a batch of 8 costs about what one
        scalar propagation does (e.g. the columns of a finite-difference Hessian). Raises
        ``FloatingPointError`` if any propagation fails, as the scalar call does.
        """
        states0 = np.atleast_2d(np.asarray(states0, dtype=float))
        n = len(states0)
        t0 = np.broadcast_to(np.asarray(t0, dtype=float), (n,))
        t1 = np.broadcast_to(np.asarray(t1, dtype=float), (n,))
        ta = self._variational_batch_integrator()
        size = ta.batch_size
        # Lane-independent columns, broadcast over the lanes (no per-call tiling: this runs
        # ~36 times per mission evaluation).
        identity = np.eye(6).reshape(36, 1)
        pars = np.asarray(self.shared_parameters[: ta.pars.shape[0]], dtype=float)[:, None]
        out = np.empty((n, 42))
        for start in range(0, n, size):
            stop = min(start + size, n)
            # Pad the last chunk by repeating its first row.
            lanes = np.arange(start, start + size)
            lanes[stop - start :] = start
            ta.set_time(t0[lanes])
            state = ta.state
            state[:6] = states0[lanes].T
            state[6:] = identity
            ta.pars[:] = pars
            ta.propagate_until(t1[lanes])
            outcomes = [o for o, *_ in ta.propagate_res[: stop - start]]
            failed = [o for o in outcomes if o != hy.taylor_outcome.time_limit]
            if failed:
                raise FloatingPointError(f"variational propagation failed: {failed[0]}")
            out[start:stop] = np.array(ta.state).T[: stop - start]
        return out[:, :6], out[:, 6:].reshape(n, 6, 6)

    def _variational_batch_integrator(self) -> Any:
        ta = _CACHE.variational_batch.get(self.tol)
        if ta is None:
            state, shared = _symbols()
            system = hy.var_ode_sys(_equations(state, shared), hy.var_args.vars, order=1)
            size = hy.recommended_simd_size()
            ta = hy.taylor_adaptive_batch(
                system,
                np.tile(np.r_[np.ones(6), np.eye(6).ravel()][:, None], (1, size)),
                tol=self.tol,
                # Not compact: 0.6-0.7x the time of a compact batch here (AVX-512, 8 lanes),
                # ~3 ms an evaluation; ~5 s to compile once per machine, then
                # loaded from heyoka's on-disk cache (~0.1 s a process).
                compact_mode=False,
            )
            _CACHE.variational_batch[self.tol] = ta
        return ta

    def _batch_integrator(self) -> Any:
        ta = _CACHE.batch.get(self.tol)
        if ta is None:
            state, shared = _symbols()
            size = hy.recommended_simd_size()
            ta = hy.taylor_adaptive_batch(
                _equations(state, shared),
                np.ones((6, size)),
                tol=self.tol,
            )
            _CACHE.batch[self.tol] = ta
        return ta

    def _variational_integrator(self) -> Any:
        ta = _CACHE.variational.get(self.tol)
        if ta is None:
            state, shared = _symbols()
            system = hy.var_ode_sys(_equations(state, shared), hy.var_args.vars, order=1)
            # Compact mode: the expanded variational system takes ~15 s to compile.
            ta = hy.taylor_adaptive(
                system,
                np.r_[np.ones(6), np.eye(6).ravel()],
                tol=self.tol,
                compact_mode=True,
            )
            _CACHE.variational[self.tol] = ta
        return ta
