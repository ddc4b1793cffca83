"""The deorbit stage (patent step 103): ground-track forecast, two-body estimate, SQP.

1. Forecast the preparation orbit's ground track under J2 over the horizon and
   list its passes through the entry region (:mod:`.forecast`).
2. For the first such pass, size a tangential impulse by energy and angular
   momentum for the target entry angle (:mod:`.estimate`); its central angle,
   divided by the orbit's angular rate, places the burn before the virtual entry
   point.
3. Correct the burn epoch and the impulse vector with SLSQP under J2
   (:mod:`.correction`). If the pass cannot be met within the limits, the next
   pass is tried, up to ``solver.max_passes``.
4. With ``solver.pass_cost_margin_mps``, a pass met only at a price is passed over
   too: its corrected impulse must lie within the margin of the two-body tangential
   impulse at the shallowest allowed entry angle (:func:`pass_cost_bound_mps`). J2 moves
   a freely placed burn by well under a metre per second from that impulse; a pass whose
   burn would fall before the preparation orbit begins is met by a burn pinned at its
   start and steered by a radial component that costs tens of m/s more, rising within a
   quarter of an hour of separation delay. Without the rule the first pass is taken at
   any price, and the mission's cost jumps where the pinned burn begins; with it, the
   cost stays within the margin and the mission waits for the next pass (its time steps
   by a pass instead). If no pass within the horizon (and ``max_passes``) meets the
   bound, the result is infeasible, its reason listing the passes passed over and their
   price: the pass model of the surrogates finds no usable pass there either.

Every failure comes back as an infeasible result with its reason; nothing raises
out of :func:`solve_deorbit` on a numerical failure.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pandas as pd

from ovtraj.astro.elements import orbital_period
from ovtraj.astro.frames import (
    ecef_to_geocentric,
    eci_to_ecef,
    flight_path_angle,
    great_circle_distance,
    heading,
    relative_velocity_state,
)
from ovtraj.astro.propagation import OrbitPropagator
from ovtraj.astro.vectors import cross
from ovtraj.deadline import Deadline
from ovtraj.deorbit.correction import Correction, DescentModel, correct_burn
from ovtraj.deorbit.estimate import TangentialDeorbit, tangential_deorbit
from ovtraj.deorbit.forecast import Forecast, TrackPass, forecast_passes
from ovtraj.deorbit.inputs import DeorbitInput
from ovtraj.deorbit.result import DeorbitResult


def propagator_for(inp: DeorbitInput) -> OrbitPropagator:
    return OrbitPropagator(inp.earth, tol=inp.integrator_tol, earth_angle0_rad=inp.earth_angle0_rad)


def forecast_of(inp: DeorbitInput, propagator: OrbitPropagator | None = None) -> Forecast:
    """The ground-track forecast of the stage's problem: passes by the entry point over its
    horizon (:func:`~ovtraj.deorbit.forecast.forecast_passes`)."""
    return forecast_passes(
        propagator or propagator_for(inp),
        inp.state0,
        inp.horizon_s,
        inp.entry,
        time_tolerance_s=inp.solver.nearest_point_tolerance_s,
    )


def burn_estimate(inp: DeorbitInput, state: np.ndarray, fpa_rad: float) -> TangentialDeorbit:
    """Two-body tangential impulse from the radius of ``state`` for the entry angle."""
    earth = inp.earth
    return tangential_deorbit(
        float(np.linalg.norm(state[:3])),
        earth.radius + inp.entry.altitude_m,
        fpa_rad,
        earth.mu,
    )


def pass_cost_bound_mps(inp: DeorbitInput, track_pass: TrackPass) -> float:
    """The dearest impulse [m/s] at which ``track_pass`` is taken: the two-body tangential
    impulse from the pass's radius at the shallowest allowed entry angle (the cheapest
    entry) plus ``solver.pass_cost_margin_mps``; infinite without a margin."""
    margin = inp.solver.pass_cost_margin_mps
    if margin is None:
        return math.inf
    return burn_estimate(inp, track_pass.state, inp.entry.fpa_max_rad).dv_mps + margin


def first_burn_time_s(track_pass: TrackPass, estimate: TangentialDeorbit) -> float:
    """Burn epoch that puts the entry a central angle after the burn, at the virtual point."""
    r, v = track_pass.state[:3], track_pass.state[3:]
    angular_rate = float(np.linalg.norm(cross(r, v))) / float(r @ r)
    return track_pass.t_s - estimate.central_angle_rad / angular_rate


def solve_deorbit(inp: DeorbitInput) -> DeorbitResult:
    """Minimum-impulse deorbit burn to the entry region; see the module notes.

    The whole solve stops at ``solver.time_limit_s`` (wall time): the result is then
    infeasible and its reason names the limit.
    """
    start = time.perf_counter()
    deadline = Deadline(inp.solver.time_limit_s, "deorbit.solver.time_limit_s")
    propagator = propagator_for(inp)
    forecast = forecast_of(inp, propagator)
    candidates = forecast.in_region
    if not candidates:
        return DeorbitResult(False, forecast.reason, inp.epoch, wall_time_s=_since(start))
    try:
        shallowest = burn_estimate(inp, candidates[0].state, inp.entry.fpa_max_rad)
    except ValueError as err:
        return DeorbitResult(False, str(err), inp.epoch, wall_time_s=_since(start))
    if shallowest.dv_mps > inp.max_impulse_mps * inp.solver.estimate_margin:
        return DeorbitResult(
            False,
            f"impulse limit {inp.max_impulse_mps:g} m/s is below the "
            f"{shallowest.dv_mps:.1f} m/s the shallowest allowed entry angle "
            f"({math.degrees(inp.entry.fpa_max_rad):g} deg) needs (two-body estimate)",
            inp.epoch,
            passes_in_region=len(candidates),
            wall_time_s=_since(start),
        )
    r0 = float(np.linalg.norm(inp.state0[:3]))
    period = float(orbital_period(r0, mu=inp.earth.mu))
    model = DescentModel(
        propagator, forecast.trajectory, inp.entry, inp.max_descent_revolutions * period
    )
    search = _PassSearch(inp, model, deadline)
    search.run(candidates)
    if search.best is None:
        reason = "; ".join(search.reasons) or "no pass could be tried"
        return DeorbitResult(False, reason, inp.epoch, wall_time_s=_since(start))
    correction, track_pass, estimate = search.chosen or search.best
    feasible = search.chosen is not None
    return _result(
        inp,
        propagator,
        forecast,
        correction,
        track_pass,
        estimate,
        feasible=feasible,
        reason=None if feasible else "; ".join(search.reasons),
        passes_in_region=len(candidates),
        passes_tried=search.tried,
        propagations=model.propagations + 1,
        wall_time_s=_since(start),
    )


# A pass's corrected burn, the pass and its two-body estimate.
_Option = tuple[Correction, TrackPass, TangentialDeorbit]


class _PassSearch:
    """The passes tried in turn (module notes, 2-4): the first met within the cost bound
    is ``chosen``; ``best`` is the least violation of all; ``reasons`` say why each pass
    passed over was."""

    def __init__(self, inp: DeorbitInput, model: DescentModel, deadline: Deadline) -> None:
        self.inp = inp
        self.model = model
        self.deadline = deadline
        self.tried = 0
        self.reasons: list[str] = []
        self.best: _Option | None = None  # the least violation
        self.chosen: _Option | None = None  # accepted within the cost bound

    def run(self, candidates: list[TrackPass]) -> None:
        inp, deadline = self.inp, self.deadline
        for track_pass in candidates:
            if self.tried >= inp.solver.max_passes:
                break
            if deadline.expired():
                self.reasons.append(deadline.reason(self.tried, "passes"))
                break
            estimate = burn_estimate(inp, track_pass.state, inp.entry.fpa_target_rad)
            burn_t0 = first_burn_time_s(track_pass, estimate)
            if burn_t0 + inp.solver.burn_window_s < 0.0:
                self.reasons.append(
                    f"pass at {track_pass.t_s:.0f} s: the burn would precede the epoch"
                )
                continue
            self.tried += 1
            correction = self._correct(burn_t0, estimate)
            if self.best is None or correction.max_violation < self.best[0].max_violation:
                self.best = (correction, track_pass, estimate)
            if _accepted(correction, inp):
                if self._within_cost(correction, track_pass):
                    self.chosen = (correction, track_pass, estimate)
                    break
                continue
            self.reasons.append(f"pass at {track_pass.t_s:.0f} s: {_failure(correction, inp)}")
            if correction.limit is not None and deadline.reached:
                break

    def _correct(self, burn_t0: float, estimate: TangentialDeorbit) -> Correction:
        """SLSQP from the two-body estimate: a retrograde impulse at ``burn_t0`` [s]."""
        inp = self.inp
        return correct_burn(
            self.model,
            burn_t0,
            np.array([0.0, -estimate.dv_mps, 0.0]),
            dv_max_mps=inp.max_impulse_mps,
            t_min_s=0.0,
            t_max_s=inp.horizon_s,
            settings=inp.solver,
            deadline=self.deadline,
        )

    def _within_cost(self, correction: Correction, track_pass: TrackPass) -> bool:
        """Whether the accepted ``correction`` lies within the pass's cost bound; if not,
        the reason is kept."""
        impulse = float(np.linalg.norm(correction.shot.dv_rsw_mps))
        bound = pass_cost_bound_mps(self.inp, track_pass)
        if impulse <= bound:
            return True
        self.reasons.append(
            f"pass at {track_pass.t_s:.0f} s: met by {impulse:.2f} m/s, above the "
            f"{bound:.2f} m/s of deorbit.solver.pass_cost_margin_mps"
        )
        return False


def _since(start: float) -> float:
    return time.perf_counter() - start


def _accepted(correction: Correction, inp: DeorbitInput) -> bool:
    """Entry reached, constraints met, and SLSQP not stopped by a limit."""
    return (
        correction.limit is None
        and correction.shot.reached
        and correction.max_violation <= inp.solver.constraint_tolerance
    )


def _failure(correction: Correction, inp: DeorbitInput) -> str:
    """The constraints a correction left violated, in words."""
    c = correction.constraints
    tol = inp.solver.constraint_tolerance
    words = []
    if not correction.shot.reached:
        words.append(f"the descent does not reach {inp.entry.altitude_m / 1e3:g} km")
    if min(c["latitude_upper"], c["latitude_lower"]) < -tol:
        words.append("entry latitude outside the region")
    if min(c["longitude_upper"], c["longitude_lower"]) < -tol:
        words.append("entry longitude outside the region")
    if min(c["fpa_above_min"], c["fpa_below_max"]) < -tol:
        words.append(f"entry flight-path angle {math.degrees(correction.shot.fpa_rad):.3f} deg")
    if c["impulse_limit"] < -tol:
        dv = float(np.linalg.norm(correction.shot.dv_rsw_mps))
        words.append(f"impulse {dv:.1f} m/s above the limit {inp.max_impulse_mps:g} m/s")
    if correction.limit is not None:
        words.insert(0, f"SLSQP stopped: {correction.limit}")
    detail = ", ".join(words) or "constraints not met"
    return f"{detail} (SLSQP: {correction.message}, {correction.iterations} iterations)"


def _result(
    inp: DeorbitInput,
    propagator: OrbitPropagator,
    forecast: Forecast,
    correction: Correction,
    track_pass: TrackPass,
    estimate: TangentialDeorbit,
    **extra: object,
) -> DeorbitResult:
    earth = inp.earth
    shot = correction.shot
    r, v = shot.entry_state[:3], shot.entry_state[3:]
    v_rel = relative_velocity_state(r, v, omega=earth.omega)
    entry = inp.entry
    return DeorbitResult(
        epoch=inp.epoch,
        burn_t_s=shot.burn_t_s,
        dv_eci_mps=shot.dv_eci_mps,
        dv_rsw_mps=shot.dv_rsw_mps,
        entry_t_s=shot.entry_t_s,
        entry_r_eci_m=r,
        entry_v_eci_mps=v,
        entry_latitude_rad=shot.latitude_rad,
        entry_longitude_rad=shot.longitude_rad,
        entry_altitude_m=float(np.linalg.norm(r)) - earth.radius,
        entry_speed_mps=float(np.linalg.norm(v)),
        entry_fpa_rad=shot.fpa_rad,
        entry_relative_speed_mps=float(np.linalg.norm(v_rel)),
        entry_relative_fpa_rad=float(flight_path_angle(r, v_rel)),
        entry_heading_rad=float(heading(r, v_rel)),
        entry_error_m=float(
            great_circle_distance(
                shot.latitude_rad,
                shot.longitude_rad,
                entry.latitude_rad,
                entry.longitude_rad,
                radius=earth.radius,
            )
        ),
        virtual_entry_t_s=track_pass.t_s,
        virtual_entry_latitude_rad=track_pass.latitude_rad,
        virtual_entry_longitude_rad=track_pass.longitude_rad,
        estimate_dv_mps=estimate.dv_mps,
        estimate_central_angle_rad=estimate.central_angle_rad,
        estimate_time_of_flight_s=estimate.time_of_flight_s,
        iterations=correction.iterations,
        solver_message=correction.message,
        constraints=correction.constraints,
        trajectory=trajectory_table(inp, propagator, forecast, correction),
        **extra,
    )


def trajectory_table(
    inp: DeorbitInput, propagator: OrbitPropagator, forecast: Forecast, correction: Correction
) -> pd.DataFrame:
    """Preparation orbit up to the burn, then the descent to the entry altitude.

    Columns: time [s from the epoch], phase, ECI position and velocity, altitude,
    geocentric latitude and longitude of the sub-satellite point (the ground
    track), inertial speed and flight-path angle.
    """
    shot = correction.shot
    step = inp.trajectory_step_s
    t_wait = np.r_[np.arange(0.0, shot.burn_t_s, step), shot.burn_t_s]
    t_down = np.r_[np.arange(shot.burn_t_s, shot.entry_t_s, step), shot.entry_t_s]
    wait = forecast.trajectory.dense(t_wait)
    after_burn = np.r_[shot.state_before[:3], shot.state_before[3:] + shot.dv_eci_mps]
    try:
        down = propagator.propagate_grid(after_burn, shot.burn_t_s, t_down)
    except RuntimeError:  # the shot flew this arc; an arc that cannot be sampled has no rows
        down = np.empty((0, 6))
    t = np.r_[t_wait, t_down[: len(down)]]
    states = np.vstack([wait, down])
    earth = inp.earth
    theta = inp.earth_angle0_rad + earth.omega * t
    lat, lon, alt = ecef_to_geocentric(eci_to_ecef(states[:, :3], theta), radius=earth.radius)
    table = pd.DataFrame(
        {
            "time_s": t,
            "phase": ["preparation"] * len(t_wait) + ["descent"] * len(down),
            "x_m": states[:, 0],
            "y_m": states[:, 1],
            "z_m": states[:, 2],
            "vx_mps": states[:, 3],
            "vy_mps": states[:, 4],
            "vz_mps": states[:, 5],
            "altitude_km": np.asarray(alt) / 1e3,
            "latitude_deg": np.degrees(lat),
            "longitude_deg": np.degrees(lon),
            "speed_mps": np.linalg.norm(states[:, 3:], axis=1),
            "fpa_deg": np.degrees(flight_path_angle(states[:, :3], states[:, 3:])),
        }
    )
    return table
