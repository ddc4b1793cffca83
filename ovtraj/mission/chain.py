"""The whole-mission chain for one design point (SPEC step 5).

Design ``(H_P0, H_dp, t_dsp)``: the parking (launch target) altitude, the deorbit
preparation altitude and the separation delay after the configured stay. The
chain composes the stages; it never changes their results:

1. the target, propagated under J2 to the launch day's 0 h, gives the plane;
2. launch from the launch fit at H_P0: payload, drop-to-insertion time, insertion
   time and argument of latitude; the OV starts on a circular (mean) orbit at
   H_P0 in the target's plane;
3. rendezvous with the target (patent step 102);
4. docked for ``stay_h`` plus ``t_dsp``, then the transfer to the circular
   preparation orbit H_dp (the rendezvous machinery without a target);
5. deorbit (step 103) from the end of the transfer;
6. reentry (step 104) from the deorbit's entry state.

Each stage's result reaches the plan typed (:class:`StageResults`: the launch leg, the
two rendezvous-type results, the deorbit, the entry state built once by
:func:`entry_state`, the reentry).

Totals: ``T_total`` from the drop to the terminal interface, ``dV_total`` the sum
of every OV impulse (rendezvous 2, transfer 2, deorbit 1), ``M_load`` the payload.
A stage failure ends the chain for the sample with the stage and its reason;
nothing raises out of :func:`evaluate` on a stage's numerical failure. All times
are seconds from the launch day's 0 h UTC.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any

import numpy as np
import pandas as pd

from ovtraj.astro.angles import TWO_PI
from ovtraj.astro.elements import NonsingularElements, orbital_period, rv_to_coe
from ovtraj.astro.epoch import Epoch
from ovtraj.astro.j2_elements import state_to_mean
from ovtraj.astro.propagation import OrbitPropagator, PropagationResult
from ovtraj.config import Scenario
from ovtraj.deorbit import deorbit_input, solve_deorbit
from ovtraj.deorbit.result import DeorbitResult
from ovtraj.launch.exact import SolvedLaunch
from ovtraj.launch.fourier import FourierRangeError
from ovtraj.launch.inputs import TargetPlane, target_plane_at
from ovtraj.launch.insertion import circular_insertion_state, turned_east
from ovtraj.launch.launch_fit import LaunchFit
from ovtraj.mission.plane import AimedInsertion, aim_insertion, drop_delay_s
from ovtraj.reentry import EntryState, reentry_input, solve_reentry
from ovtraj.reentry.result import ReentryResult
from ovtraj.rendezvous.result import RendezvousInput, RendezvousResult, TransferInput
from ovtraj.rendezvous.stage import circular_transfer, solve_rendezvous
from ovtraj.store.records import BOOL, FLOAT, TEXT, Column, RowColumns
from ovtraj.target_state import target_state
from ovtraj.units import S_PER_DAY, S_PER_HOUR

STAGES = ("launch", "rendezvous", "transfer", "deorbit", "reentry")
DESIGN_NAMES = ("parking_altitude_km", "preparation_altitude_km", "separation_delay_h")


@dataclass(frozen=True)
class LaunchOnDay:
    """A design's launch leg on the launch day: what the chain's launch row is read from."""

    leg: LaunchLeg
    design: MissionDesign
    day: Epoch


LAUNCH_ROW = RowColumns(
    [
        Column("source", TEXT, "launch fit or solved launch", lambda x: x.leg.source),
        Column("launcher", TEXT, "the launcher's name", lambda x: x.leg.launcher),
        Column(
            "parking_altitude_km",
            FLOAT,
            "km: the design's parking altitude (H_P0)",
            lambda x: x.design.parking_altitude_km,
        ),
        Column(
            "payload_kg", FLOAT, "kg: the payload to the parking orbit", lambda x: x.leg.payload_kg
        ),
        Column(
            "drop_time_s",
            FLOAT,
            "s from the launch day's 0 h UTC: the drop",
            lambda x: x.leg.drop_time_s,
        ),
        Column(
            "insertion_time_s",
            FLOAT,
            "s from the launch day's 0 h UTC: the insertion",
            lambda x: x.leg.insertion_time_s,
        ),
        Column(
            "insertion_u_deg",
            FLOAT,
            "deg: argument of latitude at insertion, [0, 360)",
            lambda x: x.leg.insertion_u_deg,
        ),
        Column(
            "raan_offset_deg",
            FLOAT,
            "deg: the parking orbit's mean node east of the target's at insertion",
            lambda x: x.leg.raan_offset_deg,
        ),
        Column(
            "drop_epoch_utc",
            TEXT,
            "ISO UTC of the drop",
            lambda x: x.day.plus_seconds(x.leg.drop_time_s).iso(),
        ),
        Column(
            "insertion_epoch_utc",
            TEXT,
            "ISO UTC of the insertion",
            lambda x: x.day.plus_seconds(x.leg.insertion_time_s).iso(),
        ),
        Column(
            "feasible", BOOL, "true: a launch the chain cannot fly leaves no row", lambda x: True
        ),
        Column("reason", TEXT, "null, as feasible is true", lambda x: None),
    ],
    required=("feasible",),
)
"""The chain's launch row (from the launch fit or a solved launch's row, not
:class:`ovtraj.launch.LaunchResult`)."""

LAUNCH_ROW_SCHEMA = LAUNCH_ROW.schema
"""The columns of the chain's launch row, as stored."""


def _design_value(name: str) -> Any:
    return lambda record: float(getattr(record.design, name))


TOTALS = RowColumns(
    [
        *[Column(name, FLOAT, "the design variable", _design_value(name)) for name in DESIGN_NAMES],
        Column("feasible", BOOL, "every stage feasible", lambda r: r.feasible),
        Column("failed_stage", TEXT, "the stage that ended the chain", lambda r: r.failed_stage),
        Column("reason", TEXT, "why that stage failed", lambda r: r.reason),
        Column(
            "t_total_s",
            FLOAT,
            "s: the drop to the terminal interface (T_total)",
            lambda r: r.t_total_s,
        ),
        Column("dv_total_mps", FLOAT, "m/s: every OV impulse (dV_total)", lambda r: r.dv_total_mps),
        Column("m_load_kg", FLOAT, "kg: the payload (M_load)", lambda r: r.m_load_kg),
    ],
    required=(*DESIGN_NAMES, "feasible"),
)
"""The mission totals (:meth:`MissionRecord.totals`; results only: no timing)."""

TOTALS_SCHEMA = TOTALS.schema
"""The columns of :meth:`MissionRecord.totals`, as stored."""


@dataclass(frozen=True)
class MissionDesign:
    parking_altitude_km: float  # H_P0
    preparation_altitude_km: float  # H_dp
    separation_delay_h: float  # t_dsp, after the stay

    def as_dict(self) -> dict[str, float]:
        return {name: float(getattr(self, name)) for name in DESIGN_NAMES}


@dataclass(frozen=True)
class LaunchLeg:
    """The launch as the chain takes it from the launch fit (patent 5.1): times [s from
    the launch day's 0 h UTC], payload [kg], the insertion's argument of latitude [deg]
    and the ECI state the OV starts from (``mission.insertion``:
    :func:`ovtraj.launch.insertion.circular_insertion_state`, in the plane aimed at by
    :mod:`ovtraj.mission.plane`)."""

    source: str  # "launch fit" or "solved launch" (ovtraj.launch.exact)
    launcher: str
    parking_altitude_m: float
    payload_kg: float
    flight_time_s: float
    drop_time_s: float
    insertion_time_s: float
    insertion_u_deg: float
    insertion_state: np.ndarray
    # The parking orbit's mean node east of the target's at insertion [deg] (the plane aimed
    # at the rendezvous, ovtraj.mission.plane; 0: the target's plane at insertion) and the
    # fixed point that gave it (None for the patent's plane or a solved launch).
    raan_offset_deg: float = 0.0
    aim: AimedInsertion | None = None


@dataclass
class StageResults:
    """Each stage's typed result, as the chain handed it on (``None``: not reached)."""

    launch: LaunchLeg | None = None
    rendezvous: RendezvousResult | None = None
    transfer: RendezvousResult | None = None
    deorbit: DeorbitResult | None = None
    entry: EntryState | None = None  # the reentry's initial state, from the deorbit
    reentry: ReentryResult | None = None

    def missing(self) -> list[str]:
        """The stages without a result."""
        names = ("launch", "rendezvous", "transfer", "deorbit", "entry", "reentry")
        return [name for name in names if getattr(self, name) is None]


def rendezvous_settings(scenario: Scenario) -> dict[str, Any]:
    """The fields a rendezvous or transfer input takes from the scenario (besides the states
    and times): settings, the miss tolerance, the impulse limit, the integrator, the Earth."""
    return {
        "settings": scenario.rendezvous,
        "miss_tolerance_m": scenario.tolerances.miss_distance_m,
        "max_impulse_mps": scenario.vehicle.max_impulse_mps,
        "integrator_tol": scenario.tolerances.integrator,
        "earth": scenario.earth,
    }


def entry_state(deorbit: DeorbitResult) -> EntryState:
    """The reentry's initial state: the deorbit's Earth-relative state at the entry
    interface (the one place the hand-off from the deorbit to the reentry is built)."""
    return EntryState(
        epoch=deorbit.epoch.plus_seconds(deorbit.entry_t_s),
        latitude_rad=deorbit.entry_latitude_rad,
        longitude_rad=deorbit.entry_longitude_rad,
        altitude_m=deorbit.entry_altitude_m,
        speed_mps=deorbit.entry_relative_speed_mps,
        fpa_rad=deorbit.entry_relative_fpa_rad,
        heading_rad=deorbit.entry_heading_rad,
    )


@dataclass
class MissionRecord:
    """One evaluated design: each stage's own row, the totals and the trajectories."""

    design: MissionDesign
    stages: dict[str, dict[str, Any]] = field(default_factory=dict)
    trajectories: dict[str, pd.DataFrame] = field(default_factory=dict)
    feasible: bool = False
    failed_stage: str | None = None
    reason: str | None = None
    t_total_s: float | None = None
    dv_total_mps: float | None = None
    m_load_kg: float | None = None
    wall_time_s: float = 0.0  # timing of the evaluation, never part of the totals
    # Wall time of each stage reached [s], from the end of the previous one (the
    # rendezvous includes the target's propagation, the transfer the stay's coast):
    # timing, never stored with the results (benchmarks/mission.py).
    stage_time_s: dict[str, float] = field(default_factory=dict)
    _clock: float = field(default=0.0, repr=False)
    # Each stage's typed result, for the mission plan (ovtraj.mission.plan); not
    # persisted, not in totals().
    results: StageResults = field(default_factory=StageResults)

    def totals(self) -> dict[str, Any]:
        """The row of :data:`TOTALS`."""
        return TOTALS.row(self)


class _StageFailed(Exception):
    def __init__(self, stage: str, reason: str) -> None:
        super().__init__(reason)
        self.stage = stage
        self.reason = reason


class MissionContext:
    """What every sample of a scenario shares: the launch day, the plane, the fit."""

    def __init__(self, scenario: Scenario, launch_fit: LaunchFit) -> None:
        if scenario.mission is None or scenario.launch is None:
            raise ValueError("the scenario needs mission and launch sections")
        self.scenario = scenario
        self.fit = launch_fit
        self.day = Epoch.from_iso(scenario.launch.launch_date_utc)
        self.plane: TargetPlane = target_plane_at(scenario, self.day)
        self.propagator = OrbitPropagator(scenario.earth, tol=scenario.tolerances.integrator)
        self.target0 = target_state(scenario.target.orbit, scenario)
        self.target_offset_s = self.day.seconds_since(scenario.epoch)

    @cached_property
    def target_ephemeris(self) -> PropagationResult:
        """The target's dense J2 trajectory in seconds from the launch day's 0 h, once per
        context: from the scenario epoch to the latest arrival any design's rendezvous can
        need (the launch day, the longest wait, twice the burn-epoch window, two target
        periods for the coverage of a transfer shorter than half of one). A stage that needs
        more propagates its own; the span depends on the scenario only, so every design's
        result is the same in any process and any order.
        """
        settings = self.scenario.rendezvous
        mu = self.scenario.earth.mu
        target = rv_to_coe(self.target0[:3], self.target0[3:], mu=mu)
        period = float(orbital_period(target.a, mu=mu))
        horizon = (
            S_PER_DAY + settings.max_wait_time_s + 2.0 * settings.burn_epoch_window_s + 2.0 * period
        )
        result = self.propagator.propagate(self.target0, -self.target_offset_s, horizon, dense=True)
        if not result.ok:
            raise _StageFailed("rendezvous", f"target propagation failed: {result.message}")
        return result

    def target_at(self, t_s: float) -> np.ndarray:
        """Target ECI state ``t_s`` after the launch day's 0 h (J2)."""
        ephemeris = self.target_ephemeris
        if ephemeris.t0 <= t_s <= ephemeris.t:
            return ephemeris.state_at(t_s)
        result = self.propagator.propagate(self.target0, -self.target_offset_s, t_s)
        if not result.ok:
            raise _StageFailed("rendezvous", f"target propagation failed: {result.message}")
        return result.state

    def propagate(self, state: np.ndarray, t0: float, t1: float, stage: str) -> np.ndarray:
        result = self.propagator.propagate(state, t0, t1)
        if not result.ok:
            raise _StageFailed(stage, f"propagation failed: {result.message}")
        return result.state


def evaluate(
    context: MissionContext, design: MissionDesign, *, launch: SolvedLaunch | None = None
) -> MissionRecord:
    """Run the chain for one design; see the module notes.

    ``launch``: the launch solved at the design's parking altitude
    (:func:`ovtraj.launch.exact.cached_launch_at`) instead of the launch fit: the OV
    then starts from the solved ascent's insertion state, not the idealised circular one.
    """
    start = time.perf_counter()
    record = MissionRecord(design=design, _clock=start)
    try:
        _run(context, design, record, launch)
        record.feasible = True
    except _StageFailed as failure:
        record.failed_stage, record.reason = failure.stage, failure.reason
    record.wall_time_s = time.perf_counter() - start
    return record


def launch_leg(ctx: MissionContext, design: MissionDesign) -> LaunchLeg:
    """The launch as the chain models it from the launch fit: the insertion every DoE and
    verification evaluation starts from, and the one a plan's launch is solved to fly to
    (:func:`ovtraj.launch.exact.cached_launch_to`). Raises :class:`ValueError` (with the
    reason) outside the fit's range."""
    try:
        return _launch_leg(ctx, design, None)
    except _StageFailed as failure:
        raise ValueError(failure.reason) from None


def _launch_leg(
    ctx: MissionContext, design: MissionDesign, solved: SolvedLaunch | None
) -> LaunchLeg:
    """The launch from the fit (``mission.insertion``'s circular insertion), or the solved
    one."""
    altitude_m = design.parking_altitude_km * 1e3
    if solved is not None:
        if not solved.feasible:
            raise _StageFailed("launch", solved.reason or "the solved launch is infeasible")
        if abs(solved.altitude_m - altitude_m) > 1e-6:
            raise _StageFailed(
                "launch",
                f"the solved launch aims at {solved.altitude_m / 1e3:.6f} km, the design's "
                f"parking altitude is {design.parking_altitude_km:.6f} km",
            )
        return LaunchLeg(
            source="solved launch",
            launcher=ctx.fit.launcher,
            parking_altitude_m=altitude_m,
            payload_kg=solved.value("payload_kg"),
            flight_time_s=solved.value("flight_time_s"),
            drop_time_s=solved.value("drop_time_s"),
            insertion_time_s=solved.value("insertion_time_s"),
            insertion_u_deg=solved.value("insertion_u_deg") % 360.0,
            insertion_state=solved.insertion_state,
            raan_offset_deg=float(solved.row.get("raan_offset_deg") or 0.0),
        )
    try:
        launch = ctx.fit.evaluate(altitude_m)
    except FourierRangeError as err:
        raise _StageFailed("launch", str(err)) from None
    settings = ctx.scenario.mission.insertion
    orbit = "mean_circular" if settings is None else settings.orbit
    t_fit, flight_time = launch["insertion_time_s"], launch["flight_time_s"]
    u_ins = math.radians(launch["insertion_u_deg"])
    plane, earth = ctx.plane, ctx.scenario.earth

    # The insertion with its node at 0; J2 being axisymmetric, any other node is this
    # state turned east (its mean elements move in node only): one solve per design.
    base = circular_insertion_state(orbit, altitude_m, u_ins, plane.inclination_rad, 0.0, earth)

    def insertion_at(raan_offset: float) -> tuple[float, np.ndarray, NonsingularElements]:
        t_ins = t_fit + drop_delay_s(raan_offset, earth.omega, plane.raan_rate_rad_s)
        if t_ins - flight_time < 0.0:  # the launch stage's rule: the first drop after 0 h
            t_ins += drop_delay_s(TWO_PI, earth.omega, plane.raan_rate_rad_s)
        raan = plane.raan_at(t_ins) + raan_offset
        return t_ins, turned_east(base, raan), replace(base_mean, raan=base_mean.raan + raan)

    if settings is None or settings.plane == "launch":
        t_ins, parked = t_fit, turned_east(base, plane.raan_at(t_fit))
        aim = None
    else:
        base_mean = state_to_mean(base[:3], base[3:], mu=earth.mu, radius=earth.radius, j2=earth.j2)
        aim = aim_insertion(insertion_at, ctx.target_at, earth, settings.aim)
        t_ins, parked = aim.insertion_time_s, aim.state
    return LaunchLeg(
        source="launch fit",
        launcher=ctx.fit.launcher,
        parking_altitude_m=altitude_m,
        payload_kg=launch["payload_kg"],
        flight_time_s=flight_time,
        drop_time_s=t_ins - flight_time,
        insertion_time_s=t_ins,
        insertion_u_deg=launch["insertion_u_deg"] % 360.0,
        insertion_state=parked,
        raan_offset_deg=0.0 if aim is None else math.degrees(aim.raan_offset_rad),
        aim=aim,
    )


def _run(
    ctx: MissionContext,
    design: MissionDesign,
    record: MissionRecord,
    solved: SolvedLaunch | None = None,
) -> None:
    """The stages in turn (module notes, 2-6) and the totals; a stage that fails raises
    :class:`_StageFailed`."""
    leg = _launch(ctx, design, record, solved)
    common = rendezvous_settings(ctx.scenario)
    rdv = _rendezvous(ctx, leg, record, common)
    transfer = _transfer(ctx, design, rdv, record, common)
    deorbit = _deorbit(ctx, transfer, record)
    reentry = _reentry(ctx, deorbit, record)
    t_terminal = transfer.arrival_time_s + deorbit.entry_t_s + reentry.flight_time_s
    record.t_total_s = t_terminal - leg.drop_time_s
    record.dv_total_mps = rdv.dv_total_mps + transfer.dv_total_mps + deorbit.dv_mps
    record.m_load_kg = leg.payload_kg


def _launch(
    ctx: MissionContext, design: MissionDesign, record: MissionRecord, solved: SolvedLaunch | None
) -> LaunchLeg:
    """2. The launch from the fit (or the solved launch)."""
    leg = _launch_leg(ctx, design, solved)
    record.results.launch = leg
    record.stages["launch"] = LAUNCH_ROW.row(LaunchOnDay(leg, design, ctx.day))
    _lap(record, "launch")
    return leg


def _rendezvous(
    ctx: MissionContext, leg: LaunchLeg, record: MissionRecord, common: dict[str, Any]
) -> RendezvousResult:
    """3. The rendezvous with the target from the insertion."""
    t_ins = leg.insertion_time_s
    rdv = solve_rendezvous(
        RendezvousInput(
            epoch=ctx.day,
            t0_s=t_ins,
            chaser_state=leg.insertion_state,
            target_state=ctx.target_at(t_ins),
            target_coast=ctx.target_ephemeris,
            **common,
        )
    )
    _keep(record, "rendezvous", rdv)
    return rdv


def _transfer(
    ctx: MissionContext,
    design: MissionDesign,
    rdv: RendezvousResult,
    record: MissionRecord,
    common: dict[str, Any],
) -> RendezvousResult:
    """4. The stay, the separation and the transfer to the preparation orbit."""
    scenario = ctx.scenario
    t_sep = rdv.arrival_time_s + S_PER_HOUR * (scenario.mission.stay_h + design.separation_delay_h)
    docked = ctx.propagate(rdv.final_state, rdv.arrival_time_s, t_sep, "transfer")
    transfer = circular_transfer(
        TransferInput(
            epoch=ctx.day,
            t0_s=t_sep,
            chaser_state=docked,
            target_altitude_m=design.preparation_altitude_km * 1e3,
            burn_time_s=t_sep,
            **common,
        )
    )
    _keep(record, "transfer", transfer)
    return transfer


def _deorbit(
    ctx: MissionContext, transfer: RendezvousResult, record: MissionRecord
) -> DeorbitResult:
    """5. The deorbit from the end of the transfer."""
    deorbit = solve_deorbit(
        deorbit_input(
            ctx.scenario,
            state0=transfer.final_state,
            epoch=ctx.day.plus_seconds(transfer.arrival_time_s),
        )
    )
    _keep(record, "deorbit", deorbit)
    return deorbit


def _reentry(ctx: MissionContext, deorbit: DeorbitResult, record: MissionRecord) -> ReentryResult:
    """6. The reentry from the deorbit's entry state."""
    entry = entry_state(deorbit)
    record.results.entry = entry
    reentry = solve_reentry(reentry_input(ctx.scenario, entry=entry))
    _keep(record, "reentry", reentry)
    return reentry


def _keep(record: MissionRecord, stage: str, result: Any) -> None:
    """The stage's row, typed result and trajectory into the record, and its lap; raises
    :class:`_StageFailed` when the stage is infeasible."""
    record.stages[stage] = result.to_row()
    setattr(record.results, stage, result)
    record.trajectories[stage] = result.trajectory
    _lap(record, stage)
    if not result.feasible:
        raise _StageFailed(stage, result.reason or "infeasible")


def _lap(record: MissionRecord, stage: str) -> None:
    """The stage's wall time: since the previous lap (or the evaluation's start)."""
    now = time.perf_counter()
    record.stage_time_s[stage] = now - record._clock
    record._clock = now
