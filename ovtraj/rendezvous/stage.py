"""The rendezvous stage: modified Hohmann transfer under J2 (patent step 102).

1. Two-body Hohmann between the mean radii: first impulse, transfer time, lead angle.
2. Phasing: the chaser waits in its parking orbit until the target leads it by
   the lead angle (J2 secular rates for the estimate, then Newton steps on the
   propagated phase).
3. Interior-point correction of the first impulse, the transfer time and the
   burn epoch under J2 until the arrival miss is below epsilon_dis
   (:mod:`ovtraj.rendezvous.correction`).
4. Second impulse v_target - v_chaser at arrival; the actual lead angle is the
   phase at the corrected burn epoch.

:func:`circular_transfer` reuses the same machinery for a transfer to a circular
orbit with no target: a virtual target on the mean-circular destination orbit is
placed where the Hohmann arc arrives, so the result is a J2-consistent circular
orbit (used for the transfer to the deorbit preparation orbit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from ovtraj.astro.elements import NonsingularElements, mean_motion
from ovtraj.astro.frames import eci_to_rsw
from ovtraj.astro.j2_elements import mean_to_state, state_to_mean
from ovtraj.astro.propagation import OrbitPropagator, PropagationResult
from ovtraj.deadline import Deadline
from ovtraj.rendezvous.correction import CorrectionProblem, CorrectionResult, correct_transfer
from ovtraj.rendezvous.hohmann import HohmannTransfer, hohmann, lead_angle
from ovtraj.rendezvous.phasing import (
    mean_argument_of_latitude_rate,
    phase_angle,
    plane_difference,
    refine_wait,
    secular_phasing,
)
from ovtraj.rendezvous.result import (
    Impulse,
    RendezvousInput,
    RendezvousResult,
    TransferInput,
    TransferKind,
)

# Newton steps on the propagated phase; the J2 secular estimate is within a
# fraction of a degree, and each step gains several digits.
_PHASING_NEWTON_STEPS = 3
# Coasts are propagated this fraction of the Hohmann time beyond the latest epoch the
# correction may use, so finite-difference steps at a bound never leave them.
_COVERAGE_PAD = 0.01
# The first coasts reach this fraction of the Hohmann time past the estimated burn, so the
# Newton steps on the wait (which move it by seconds to minutes) rarely need a longer one.
_PHASING_SLACK = 0.5


class Infeasible(Exception):
    """Raised inside the stage to stop early with a reason; never escapes it."""


class WaitTooLong(Infeasible):
    """The phasing wait exceeds ``max_wait_time_s``: the result keeps the wait it needs
    (``phasing_wait_s``)."""

    def __init__(self, wait_s: float, limit_s: float) -> None:
        super().__init__(
            f"phasing needs a wait of {wait_s:.0f} s, more than rendezvous.max_wait_time_s "
            f"({limit_s:.0f} s)"
        )
        self.wait_s = wait_s


@dataclass(frozen=True)
class _Plan:
    hohmann: HohmannTransfer
    lead_two_body: float
    burn_time_s: float
    chaser_coast: PropagationResult
    target_coast: PropagationResult
    burn_window_s: float
    plane_difference: float


def _propagator(inp: RendezvousInput | TransferInput) -> OrbitPropagator:
    return OrbitPropagator(inp.earth, tol=inp.integrator_tol, earth_angle0_rad=inp.epoch.gmst_rad())


def _check_state(name: str, state: np.ndarray, radius: float) -> np.ndarray:
    state = np.asarray(state, dtype=float).reshape(-1)
    if state.shape != (6,) or not np.all(np.isfinite(state)):
        raise ValueError(f"{name} must be a finite ECI state of 6 numbers (m, m/s)")
    if np.linalg.norm(state[:3]) <= radius:
        raise ValueError(f"{name} lies inside the Earth (|r| <= {radius:.0f} m)")
    return state


def _mean(state: np.ndarray, inp: RendezvousInput | TransferInput) -> NonsingularElements:
    e = inp.earth
    return state_to_mean(state[:3], state[3:], mu=e.mu, radius=e.radius, j2=e.j2)


def _check_circular(who: str, mean: NonsingularElements, limit: float) -> None:
    e = math.hypot(float(mean.ex), float(mean.ey))
    if e > limit:
        raise Infeasible(
            f"{who} orbit is not near-circular: mean eccentricity {e:.4g} exceeds "
            f"{limit:g} (rendezvous.max_eccentricity); a Hohmann transfer assumes circular orbits"
        )


def _plan_rendezvous(inp: RendezvousInput, prop: OrbitPropagator) -> _Plan:
    s, earth = inp.settings, inp.earth
    chaser0 = _check_state("chaser_state", inp.chaser_state, earth.radius)
    target0 = _check_state("target_state", inp.target_state, earth.radius)
    secular = secular_phasing(chaser0, target0, earth)
    _check_circular("chaser", secular.mean_chaser, s.max_eccentricity)
    _check_circular("target", secular.mean_target, s.max_eccentricity)
    _check_planes(plane_difference(chaser0, target0), s.max_plane_difference_deg, "at the start")

    transfer, lead_j2, relative_rate = secular.transfer, secular.lead, secular.relative_rate
    if relative_rate == 0.0:
        raise Infeasible("chaser and target have the same period: the phase never changes")
    wait = secular.wait_s
    if wait > s.max_wait_time_s + s.burn_epoch_window_s:
        # Beyond the limit by more than the burn window: the secular estimate, unrefined
        # (refining would propagate both orbits over the whole longer wait).
        raise WaitTooLong(wait, s.max_wait_time_s)

    hi = s.transfer_time_bounds[1]
    pad = _COVERAGE_PAD * transfer.transfer_time_s
    chaser_coast = None
    given = inp.target_coast
    target_coast = given if given is not None and given.t0 <= inp.t0_s <= given.t else None

    def cover(burn_time: float) -> None:
        """Dense coasts spanning every burn epoch and arrival the correction may try."""
        nonlocal chaser_coast, target_coast
        latest_burn = burn_time + s.burn_epoch_window_s + pad
        chaser_coast = _covering(prop, "chaser", chaser0, inp.t0_s, chaser_coast, latest_burn)
        latest_arrival = latest_burn + hi * transfer.transfer_time_s
        target_coast = _covering(prop, "target", target0, inp.t0_s, target_coast, latest_arrival)

    def phase_at(wait_s: float) -> float:
        cover(inp.t0_s + wait_s)
        t = inp.t0_s + wait_s
        return phase_angle(chaser_coast.state_at(t), target_coast.state_at(t)[:3])

    cover(inp.t0_s + wait + _PHASING_SLACK * transfer.transfer_time_s)
    wait = refine_wait(wait, lead_j2, relative_rate, phase_at, iterations=_PHASING_NEWTON_STEPS)
    if wait > s.max_wait_time_s:
        raise WaitTooLong(wait, s.max_wait_time_s)
    burn_time = inp.t0_s + wait
    cover(burn_time)
    planes = plane_difference(chaser_coast.state_at(burn_time), target_coast.state_at(burn_time))
    _check_planes(planes, s.max_plane_difference_deg, "at the first burn")
    # The corrected burn epoch may move by +-window, but not before t0.
    window = min(s.burn_epoch_window_s, wait)
    return _Plan(
        transfer,
        _two_body_lead(transfer, earth.mu),
        burn_time,
        chaser_coast,
        target_coast,
        window,
        planes,
    )


def _two_body_lead(transfer: HohmannTransfer, mu: float) -> float:
    """Lead angle with the target's two-body mean motion (patent step 102, classic formula)."""
    return lead_angle(transfer, mean_motion(transfer.r2_m, mu=mu))


def _covering(
    prop: OrbitPropagator,
    name: str,
    state0: np.ndarray,
    t0: float,
    coast: PropagationResult | None,
    until: float,
) -> PropagationResult:
    """``coast`` if it reaches ``until``, else a new dense propagation that does."""
    if coast is not None and coast.t >= until:
        return coast
    coast = prop.propagate(state0, t0, until, dense=True)
    if not coast.ok:
        raise Infeasible(f"{name} coast propagation failed: {coast.message}")
    return coast


def _plan_transfer(inp: TransferInput, prop: OrbitPropagator) -> _Plan:
    s, earth = inp.settings, inp.earth
    chaser0 = _check_state("chaser_state", inp.chaser_state, earth.radius)
    if not inp.target_altitude_m > 0:
        raise ValueError(f"target_altitude_m must be > 0, got {inp.target_altitude_m}")
    burn_time = inp.t0_s if inp.burn_time_s is None else float(inp.burn_time_s)
    if burn_time < inp.t0_s:
        raise ValueError(f"burn_time_s ({burn_time}) must not precede t0_s ({inp.t0_s})")
    chaser_coast = prop.propagate(chaser0, inp.t0_s, burn_time, dense=True)
    if not chaser_coast.ok:
        raise Infeasible(f"chaser coast propagation failed: {chaser_coast.message}")
    chaser_b = chaser_coast.state
    mean_c = _mean(chaser_b, inp)
    _check_circular("chaser", mean_c, s.max_eccentricity)

    transfer = hohmann(float(mean_c.a), earth.radius + inp.target_altitude_m, earth.mu)
    destination = NonsingularElements(
        a=transfer.r2_m, ex=0.0, ey=0.0, i=float(mean_c.i), raan=float(mean_c.raan), u=0.0
    )
    lead_j2 = lead_angle(transfer, mean_argument_of_latitude_rate(destination, earth))
    # The virtual target leads the chaser by the lead angle on the destination orbit.
    r_v, v_v = mean_to_state(
        replace(destination, u=float(mean_c.u) + lead_j2),
        mu=earth.mu,
        radius=earth.radius,
        j2=earth.j2,
    )
    latest_arrival = burn_time + (s.transfer_time_bounds[1] + _COVERAGE_PAD) * (
        transfer.transfer_time_s
    )
    target_coast = _covering(prop, "destination", np.r_[r_v, v_v], burn_time, None, latest_arrival)
    return _Plan(
        transfer,
        _two_body_lead(transfer, earth.mu),
        burn_time,
        chaser_coast,
        target_coast,
        0.0,
        0.0,
    )


def _check_planes(angle: float, limit_deg: float, when: str) -> None:
    if angle > math.radians(limit_deg):
        raise Infeasible(
            f"plane difference {math.degrees(angle):.3f} deg {when} exceeds "
            f"{limit_deg:g} deg (rendezvous.max_plane_difference_deg): this coplanar stage "
            "does not perform plane changes"
        )


def _solve(
    inp: RendezvousInput | TransferInput, prop: OrbitPropagator, deadline: Deadline
) -> tuple[_Plan, CorrectionResult]:
    plan = (
        _plan_rendezvous(inp, prop)
        if isinstance(inp, RendezvousInput)
        else _plan_transfer(inp, prop)
    )
    chaser_b = plan.chaser_coast.dense(plan.burn_time_s)
    direction = chaser_b[3:] / np.linalg.norm(chaser_b[3:])
    # Only the rendezvous has a plane difference, hence optima on both sides of 180 deg;
    # the transfer's virtual target lies in the chaser's own plane.
    multi = inp.settings.multi_start_fractions
    multi_start = isinstance(inp, RendezvousInput) and multi is not None
    starts = multi if multi_start else inp.settings.start_transfer_fractions
    correction = correct_transfer(
        CorrectionProblem(
            propagator=prop,
            chaser_coast=plan.chaser_coast,
            target_coast=plan.target_coast,
            burn_time_s=plan.burn_time_s,
            hohmann_time_s=plan.hohmann.transfer_time_s,
            dv_guess_eci=plan.hohmann.dv1_mps * direction,
            miss_tolerance_m=inp.miss_tolerance_m,
            transfer_time_bounds=inp.settings.transfer_time_bounds,
            start_fractions=starts,
            burn_window_s=plan.burn_window_s,
            max_iterations=inp.settings.max_iterations,
            optimality_tol=inp.settings.optimality_tol,
            initial_barrier_parameter=inp.settings.initial_barrier_parameter,
            initial_trust_radius=inp.settings.initial_trust_radius,
            deadline=deadline,
            iterations_key="rendezvous.max_iterations",
            solve_every_start=multi_start,
        )
    )
    return plan, correction


def _result(
    kind: TransferKind,
    inp: RendezvousInput | TransferInput,
    prop: OrbitPropagator,
    plan: _Plan,
    c: CorrectionResult,
) -> RendezvousResult:
    burn1 = Impulse(
        c.burn_time_s, c.dv1_eci, eci_to_rsw(c.dv1_eci, c.chaser_at_burn[:3], c.chaser_at_burn[3:])
    )
    arrival = c.burn_time_s + c.transfer_time_s
    burn2 = Impulse(
        arrival,
        c.dv2_eci,
        eci_to_rsw(c.dv2_eci, c.chaser_at_arrival[:3], c.chaser_at_arrival[3:]),
    )
    reasons = []
    if c.limit is not None:
        reasons.append(
            f"J2 correction stopped: {c.limit} (miss {c.miss_distance_m:.3g} m, "
            f"epsilon_dis {inp.miss_tolerance_m:g} m)"
        )
    elif not c.converged:
        reasons.append(
            f"J2 correction did not converge: miss {c.miss_distance_m:.3g} m > "
            f"epsilon_dis {inp.miss_tolerance_m:g} m after {c.iterations} iterations "
            f"({c.message})"
        )
    for name, burn in (("first", burn1), ("second", burn2)):
        if burn.magnitude_mps > inp.max_impulse_mps:
            reasons.append(
                f"{name} impulse {burn.magnitude_mps:.1f} m/s exceeds the OV's maximum "
                f"{inp.max_impulse_mps:g} m/s (vehicle.max_impulse_mps)"
            )
    lead = phase_angle(c.chaser_at_burn, plan.target_coast.dense(c.burn_time_s)[:3])
    final_state = c.chaser_at_arrival + np.r_[0.0, 0.0, 0.0, c.dv2_eci]
    return RendezvousResult(
        kind=kind,
        feasible=not reasons,
        reason="; ".join(reasons),
        epoch=inp.epoch,
        t0_s=inp.t0_s,
        wait_time_s=c.burn_time_s - inp.t0_s,
        phasing_wait_s=plan.burn_time_s - inp.t0_s,
        burn1=burn1,
        burn2=burn2,
        transfer_time_s=c.transfer_time_s,
        transfer_time_two_body_s=plan.hohmann.transfer_time_s,
        dv1_two_body_mps=abs(plan.hohmann.dv1_mps),
        dv2_two_body_mps=abs(plan.hohmann.dv2_mps),
        lead_angle_rad=lead,
        lead_angle_two_body_rad=plan.lead_two_body,
        plane_difference_rad=plan.plane_difference,
        miss_distance_m=c.miss_distance_m,
        initial_miss_distance_m=c.initial_miss_distance_m,
        iterations=c.iterations,
        evaluations=c.evaluations,
        solver_message=c.message,
        final_state=final_state,
        trajectory=_trajectory(inp, prop, plan, c),
    )


def _trajectory(
    inp: RendezvousInput | TransferInput,
    prop: OrbitPropagator,
    plan: _Plan,
    c: CorrectionResult,
) -> pd.DataFrame:
    step = inp.settings.trajectory_step_s
    arrival = c.burn_time_s + c.transfer_time_s
    t_wait = np.unique(np.r_[np.arange(inp.t0_s, c.burn_time_s, step), c.burn_time_s])
    t_transfer = np.unique(np.r_[np.arange(c.burn_time_s, arrival, step), arrival])
    after_burn = c.chaser_at_burn + np.r_[0.0, 0.0, 0.0, c.dv1_eci]
    try:
        transfer_arc = prop.propagate_grid(after_burn, c.burn_time_s, t_transfer)
    except RuntimeError as err:  # the correction flew this arc: not expected
        raise FloatingPointError(f"transfer arc: {err}") from None
    chaser = np.vstack([plan.chaser_coast.dense(t_wait), transfer_arc])
    times = np.r_[t_wait, t_transfer]
    # A target-less transfer's virtual target exists only from the burn on: those rows are
    # missing values (pandas NA, null in Parquet), not NaN.
    has_target = times >= plan.target_coast.t0
    target = np.zeros_like(chaser)
    target[has_target] = plan.target_coast.dense(times[has_target])
    table: dict[str, object] = {
        "t_s": times,
        "phase": ["wait"] * len(t_wait) + ["transfer"] * len(t_transfer),
    }
    axes = ("x_m", "y_m", "z_m", "vx_mps", "vy_mps", "vz_mps")
    for k, axis in enumerate(axes):
        table[f"chaser_{axis}"] = chaser[:, k]
    for k, axis in enumerate(axes):
        table[f"target_{axis}"] = _masked(target[:, k], has_target)
    table["chaser_altitude_m"] = np.linalg.norm(chaser[:, :3], axis=1) - inp.earth.radius
    table["range_m"] = _masked(np.linalg.norm(chaser[:, :3] - target[:, :3], axis=1), has_target)
    return pd.DataFrame(table)


def _masked(values: np.ndarray, valid: np.ndarray) -> pd.api.extensions.ExtensionArray:
    """Nullable float column: missing (pandas NA) where ``valid`` is False.

    Always the same dtype, so both kinds of result share one Parquet schema.
    """
    # Built from its values and mask: a tenth of pd.array then an NA assignment.
    return pd.arrays.FloatingArray(np.array(values, dtype=float), ~np.asarray(valid, dtype=bool))


def _run(kind: TransferKind, inp: RendezvousInput | TransferInput) -> RendezvousResult:
    deadline = Deadline(inp.settings.time_limit_s, "rendezvous.time_limit_s")
    prop = _propagator(inp)

    def infeasible(reason: str, phasing_wait_s: float | None = None) -> RendezvousResult:
        return RendezvousResult(
            kind=kind,
            feasible=False,
            reason=reason,
            epoch=inp.epoch,
            t0_s=inp.t0_s,
            phasing_wait_s=phasing_wait_s,
        )

    try:
        plan, correction = _solve(inp, prop, deadline)
    except WaitTooLong as why:
        return infeasible(str(why), why.wait_s)
    except Infeasible as why:
        return infeasible(str(why))
    except (FloatingPointError, np.linalg.LinAlgError) as err:
        return infeasible(f"numerical failure in the J2 correction: {err}")
    values = np.r_[correction.dv1_eci, correction.dv2_eci, correction.miss_distance_m]
    if not np.all(np.isfinite(values)):
        return infeasible(
            f"J2 correction diverged after {correction.iterations} iterations "
            f"({correction.message})"
        )
    return _result(kind, inp, prop, plan, correction)


def solve_rendezvous(inp: RendezvousInput) -> RendezvousResult:
    """Rendezvous of the chaser with the target (patent step 102); see the module doc."""
    return _run("rendezvous", inp)


def circular_transfer(inp: TransferInput) -> RendezvousResult:
    """Transfer of the chaser to a circular orbit at ``inp.target_altitude_m``, no target."""
    return _run("transfer", inp)
