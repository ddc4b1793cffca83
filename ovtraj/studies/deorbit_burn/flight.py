"""One deorbit trajectory: coast to the burn start, burn to the predicted cut-off, coast to entry.

1. Coast under J2 from the initial state to the burn-start argument of latitude u_open
   (:class:`ovtraj.astro.propagation.OrbitPropagator`, argument-of-latitude event).
2. Burn (:class:`ovtraj.studies.deorbit_burn.powered.PoweredFlight`) with dense output up to the
   longest allowed burn. Along the burn, on a grid of ``grid_step_s``, the osculating
   perigee is checked; once it is below r_E the entry is predicted
   (:func:`ovtraj.astro.entry_prediction.predict_entry`) and the cut-off margin of the
   strategy evaluated (seed sec. 2.4 and 3). The first grid interval where the margin
   changes sign brackets the cut-off; a cubic through the neighbouring grid values locates
   it, and a vectorised stencil of width ``cutoff_time_tolerance_s`` around that estimate
   confirms the bracket (``scipy.optimize.brentq`` finishes the rare case it does not).
   This stands for an engine cut at the first guidance cycle where the prediction meets
   the target, with a cycle short enough not to matter.
3. Coast from the cut-off to the entry radius (altitude event, descending) and record the
   entry state: argument of latitude, inertial flight-path angle and speed.

SI units (m, m/s, kg, s, rad). Failures (no cut-off within the longest burn, no entry) are
returned in ``FlightOutcome.reason``, never raised.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.optimize import brentq

from ovtraj.astro.angles import wrap_to_pi
from ovtraj.astro.constants import EarthModel
from ovtraj.astro.elements import (
    NonsingularElements,
    argument_of_latitude,
    nonsingular_to_rv,
    orbital_period,
)
from ovtraj.astro.entry_prediction import (
    EntryPrediction,
    cutoff_margin,
    predict_entry,
    state_perigee_radius,
)
from ovtraj.astro.frames import flight_path_angle
from ovtraj.astro.j2_elements import mean_to_state
from ovtraj.astro.propagation import AltitudeCrossing, ArgumentOfLatitudeCrossing, OrbitPropagator
from ovtraj.config.physical import default_earth
from ovtraj.studies.deorbit_burn.powered import BurnArc, PoweredFlight, ThrustSettings
from ovtraj.studies.deorbit_burn.problem import DeorbitBurnProblem

__all__ = ["FlightOutcome", "FlightSimulator", "initial_state"]

# Grid points predicted per vectorised call while looking for the cut-off bracket.
_CHUNK = 64


def _values(prediction: EntryPrediction) -> np.ndarray:
    """(3, n) table of predicted u [rad], fpa [rad], speed [m/s]."""
    return np.vstack([prediction.u_rad, prediction.fpa_rad, prediction.speed_mps])


@dataclass(frozen=True)
class FlightOutcome:
    """One flown trajectory (SI). ``entry_*`` are NaN and ``reason`` is set when it failed.

    Errors are actual minus target; the u error is wrapped to (-pi, pi].
    """

    u_open_rad: float
    t_open_s: float
    burn_duration_s: float
    dv_mps: float
    mass_after_kg: float
    entry_time_s: float
    entry_u_rad: float
    entry_fpa_rad: float
    entry_speed_mps: float
    u_error_rad: float
    fpa_error_rad: float
    speed_error_mps: float
    predicted_u_rad: float
    predicted_fpa_rad: float
    predicted_speed_mps: float
    reason: str | None = None

    @property
    def ok(self) -> bool:
        return self.reason is None


def _failed(u_open: float, reason: str, **known: float) -> FlightOutcome:
    values = dict.fromkeys(FlightOutcome.__dataclass_fields__, math.nan)
    values.update(known, u_open_rad=u_open, reason=reason)
    return FlightOutcome(**values)


def initial_state(problem: DeorbitBurnProblem, waiting: NonsingularElements) -> np.ndarray:
    """Cartesian state (6,) at t = 0 of the waiting-orbit elements (mean or osculating)."""
    earth = problem.earth
    if problem.waiting_is_mean:
        r, v = mean_to_state(waiting, mu=earth.mu, radius=earth.radius, j2=earth.j2)
    else:
        r, v = nonsingular_to_rv(waiting, mu=earth.mu)
    return np.r_[r, v]


class FlightSimulator:
    """Flies trajectories of one problem; integrators are compiled once per thread."""

    def __init__(self, problem: DeorbitBurnProblem) -> None:
        self.problem = problem
        earth = problem.earth
        guidance = problem.config.guidance
        # The coasts use no Earth-fixed events: the rotation rate is carried, not used.
        model = EarthModel(
            mu_m3_s2=earth.mu,
            equatorial_radius_m=earth.radius,
            j2=earth.j2,
            rotation_rate_rad_s=default_earth().rotation_rate_rad_s,
            g0_m_s2=earth.g0,
        )
        self.coast = OrbitPropagator(model, tol=guidance.integrator_tolerance, j2=earth.j2 > 0.0)
        self.powered = PoweredFlight(
            earth, tol=guidance.integrator_tolerance, entry_radius_m=problem.entry.radius_m
        )
        self.max_coast_s = guidance.max_coast_revolutions * float(
            orbital_period(problem.waiting.a, mu=earth.mu)
        )
        self.prediction = guidance.prediction
        self.entry_event = AltitudeCrossing(problem.entry.radius_m - earth.radius)

    def _predict(self, states: np.ndarray, strategy: int) -> tuple[EntryPrediction, np.ndarray]:
        entry = self.problem.entry
        prediction = predict_entry(
            states[:, :3],
            states[:, 3:6],
            earth=self.problem.earth,
            entry_radius=entry.radius_m,
            iterations=self.prediction.time_to_go_iterations,
        )
        return prediction, cutoff_margin(prediction, strategy, entry.u_rad, entry.fpa_rad)

    def _cutoff(self, arc: BurnArc, strategy: int) -> tuple[float, np.ndarray] | None:
        """First instant where the strategy's cut-off margin reaches 0, or None.

        Returns the instant [s] and the prediction there (u [rad], fpa [rad], speed [m/s]).
        """
        step = self.prediction.grid_step_s
        times = np.arange(arc.t0, arc.t1, step)
        times = np.append(times, arc.t1) if arc.t1 - times[-1] > 1e-9 else times
        states = arc.states(times)
        low = state_perigee_radius(states[:, :3], states[:, 3:6], self.problem.earth.mu)
        candidates = np.flatnonzero(low <= self.problem.entry.radius_m)
        if not len(candidates):
            return None
        first = int(candidates[0])
        margins = np.full(len(times), np.inf)
        for start in range(first, len(times), _CHUNK):
            chunk = slice(start, min(start + _CHUNK, len(times)))
            _, margins[chunk] = self._predict(states[chunk], strategy)
            below = np.flatnonzero(margins[chunk] <= 0.0)
            if len(below):
                k = start + int(below[0])
                break
        else:
            return None
        if k == first or not np.isfinite(margins[k - 1]):
            # The target is met as soon as the orbit reaches r_E: cut at the grazing instant.
            lo = times[k - 1] if k > 0 else times[k]
            t_cut = self._grazing_time(arc, lo, times[k])
            prediction, _ = self._predict(arc.states(np.array([t_cut])), strategy)
            return t_cut, _values(prediction)[:, 0]
        return self._refine(arc, strategy, times, margins, k)

    def _grazing_time(self, arc: BurnArc, lo: float, hi: float) -> float:
        mu, r_e = self.problem.earth.mu, self.problem.entry.radius_m

        def excess(t: float) -> float:
            s = arc.state_at(t)
            return float(state_perigee_radius(s[None, :3], s[None, 3:6], mu)[0]) - r_e

        if excess(lo) <= 0.0:
            return lo
        tol = self.prediction.cutoff_time_tolerance_s
        return float(brentq(excess, lo, hi, xtol=tol * 1e-2)) + tol

    def _refine(
        self, arc: BurnArc, strategy: int, times: np.ndarray, margins: np.ndarray, k: int
    ) -> tuple[float, np.ndarray]:
        tol = self.prediction.cutoff_time_tolerance_s
        lo, hi = times[k - 1], times[k]
        window = [j for j in range(k - 2, k + 2) if 0 <= j < len(times) and np.isfinite(margins[j])]
        guess = lo + (hi - lo) * margins[k - 1] / (margins[k - 1] - margins[k])
        if len(window) >= 3:
            spline = CubicSpline(times[window], margins[window])
            roots = [t for t in spline.roots(extrapolate=False) if lo <= t <= hi]
            if roots:
                guess = float(roots[0])
        # A stencil around the estimate: the root is confirmed inside one of its intervals
        # and interpolated linearly there (the margin is smooth on a scale of ~100 s).
        stencil = np.clip(guess + tol * np.array([-4.0, -1.0, 0.0, 1.0, 4.0]), lo, hi)
        prediction, values = self._predict(arc.states(stencil), strategy)
        for j in range(len(stencil) - 1):
            if values[j] > 0.0 >= values[j + 1]:
                weight = values[j] / (values[j] - values[j + 1])
                table = _values(prediction)
                t_cut = float(stencil[j] + (stencil[j + 1] - stencil[j]) * weight)
                return t_cut, table[:, j] + (table[:, j + 1] - table[:, j]) * weight
        t_cut = float(
            brentq(
                lambda t: float(self._predict(arc.states(np.array([t])), strategy)[1][0]),
                lo,
                hi,
                xtol=tol,
            )
        )
        prediction, _ = self._predict(arc.states(np.array([t_cut])), strategy)
        return t_cut, _values(prediction)[:, 0]

    def fly(
        self,
        state0: np.ndarray,
        mass_kg: float,
        u_open: float,
        thrust: ThrustSettings,
        strategy: int,
    ) -> FlightOutcome:
        """Fly from ``state0`` (6,) at t = 0 with the burn starting at ``u_open`` [rad]."""
        problem = self.problem
        entry = problem.entry
        coast = self.coast.propagate(
            state0, 0.0, self.max_coast_s, events=[ArgumentOfLatitudeCrossing(u_open)]
        )
        if coast.status != "terminal_event":
            return _failed(u_open, f"no burn start: u_open not reached ({coast.message})")
        t_open = coast.t
        isp_g0 = thrust.thrust_n / thrust.mass_flow_kg_s
        max_burn = (
            mass_kg
            * (1.0 - math.exp(-problem.config.guidance.max_dv_mps / isp_g0))
            / thrust.mass_flow_kg_s
        )
        try:
            arc = self.powered.burn(np.r_[coast.state, mass_kg], t_open, t_open + max_burn, thrust)
        except FloatingPointError as err:
            return _failed(u_open, f"burn: {err}", t_open_s=t_open)
        found = self._cutoff(arc, strategy)
        if found is None:
            return _failed(
                u_open,
                f"no cut-off: the strategy-{strategy} target is not predicted within "
                f"{problem.config.guidance.max_dv_mps:g} m/s of burn",
                t_open_s=t_open,
            )
        t_cut, predicted = found
        cut = arc.state_at(t_cut)
        dv = isp_g0 * math.log(mass_kg / cut[6])
        known = {
            "t_open_s": t_open,
            "burn_duration_s": t_cut - t_open,
            "dv_mps": dv,
            "mass_after_kg": float(cut[6]),
            "predicted_u_rad": float(predicted[0]),
            "predicted_fpa_rad": float(predicted[1]),
            "predicted_speed_mps": float(predicted[2]),
        }
        descent = self.coast.propagate(
            cut[:6], t_cut, t_cut + self.max_coast_s, events=[self.entry_event]
        )
        if descent.status != "terminal_event":
            return _failed(u_open, "no entry: the coast after cut-off misses r_E", **known)
        r, v = descent.state[:3], descent.state[3:6]
        u = float(argument_of_latitude(r, v))
        fpa = float(flight_path_angle(r, v))
        speed = float(np.linalg.norm(v))
        return FlightOutcome(
            u_open_rad=u_open,
            entry_time_s=descent.t,
            entry_u_rad=u,
            entry_fpa_rad=fpa,
            entry_speed_mps=speed,
            u_error_rad=wrap_to_pi(u - entry.u_rad),
            fpa_error_rad=fpa - entry.fpa_rad,
            speed_error_mps=speed - entry.speed_mps,
            **known,
        )
