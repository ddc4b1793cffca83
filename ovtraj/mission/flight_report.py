"""What a replay of a mission plan reports (:func:`ovtraj.mission.fly.fly_plan`), and its text.

The :class:`FlightReport` holds the terminal state, the miss from the landing site
and from the plan's predicted terminal point, the rendezvous arrival miss, the path
maxima against their limits (:class:`LimitCheck`), the perigee and entry-angle checks,
each impulse as applied (:class:`BurnReplay`) and ``landed_within_stated_miss``. A
replay that cannot be flown raises :class:`ReplayFailed` inside and is a report marked
failed with the reason. :func:`format_flight_report` writes it for the command line.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from ovtraj.formatting import duration, number, utc
from ovtraj.store.records import plain
from ovtraj.units import M_PER_KM

# The integrators every report names. The text is stored with each flight, so it stays as
# it is: "this module's J2 right-hand side" is ovtraj.mission.replay_orbit's.
INTEGRATORS = (
    "ascent: the launch stage's 3-DOF model and fixed-step RK4 (ovtraj.launch.ascent) from "
    "the drop with the plan's programme; "
    "orbit: scipy DOP853 on this module's J2 right-hand side (chain: heyoka Taylor); "
    "entry: scipy DOP853 between the planned bank reversals, open-loop (chain: fixed-step "
    "RK4 with the heading-corridor reversal logic)"
)


class ReplayFailed(Exception):
    """Raised inside the replay to stop with a reason; never escapes
    :func:`ovtraj.mission.fly.fly_plan`."""


@dataclass
class LimitCheck:
    """A replayed maximum (or minimum) against its limit."""

    value: float | None
    limit: float
    unit: str
    ok: bool


@dataclass
class BurnReplay:
    """A planned impulse as the replay applied it."""

    name: str
    t_s: float
    dv_mps: float
    # RSW components of the planned ECI impulse at the replay's state, minus the plan's.
    local_frame_difference_mps: float


@dataclass
class FlightReport:
    """Outcome of :func:`ovtraj.mission.fly.fly_plan`; SI units in the names, angles in degrees."""

    ok: bool  # the replay reached the terminal interface
    reason: str | None
    landed_within_stated_miss: bool
    stated_miss_m: float | None
    start: str = "drop"  # where the replay starts: the carrier's drop
    miss_distance_m: float | None = None  # from the landing site
    predicted_miss_distance_m: float | None = None  # the plan's
    prediction_distance_m: float | None = None  # from the plan's predicted terminal point
    prediction_tolerance_m: float | None = None
    matches_prediction: bool = False
    terminal_status: str | None = None
    terminal: dict[str, Any] | None = None
    # The flown ascent's insertion against the plan's (position, velocity, time, altitude,
    # speed): what the open-loop orbital phase inherits.
    insertion: dict[str, Any] | None = None
    entry: dict[str, Any] | None = None
    entry_time_difference_s: float | None = None  # replay minus plan
    entry_position_difference_m: float | None = None
    rendezvous_arrival_miss_m: float | None = None
    planned_arrival_miss_m: float | None = None
    arrival_miss_tolerance_m: float | None = None
    checks: dict[str, LimitCheck] = field(default_factory=dict)
    burns: list[BurnReplay] = field(default_factory=list)
    flight_time_s: float | None = None
    passed: bool = False  # landed within the stated miss, matches the prediction, checks hold
    plan_code_version: str | None = None
    replay_code_version: str = ""
    integrators: str = INTEGRATORS
    wall_time_s: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly; a non-finite number (never expected) becomes ``None``."""
        return plain(asdict(self))


def _scaled(value: float | None, factor: float) -> float | None:
    return None if value is None else value * factor


def format_flight_report(report: FlightReport) -> str:
    """A few lines for the command line (:mod:`ovtraj.formatting`: units, "-" for a value
    not reached)."""
    verdict = (
        "LANDED within the stated miss"
        if report.landed_within_stated_miss
        else "NOT within the stated miss"
    )
    lines = [
        f"replay from the {report.start}: {'completed' if report.ok else 'FAILED'}; {verdict}"
        + ("" if report.passed or not report.ok else " (but a check failed, see below)"),
    ]
    if report.reason:
        lines.append(f"  reason: {report.reason}")
    lines += _where_lines(report)
    lines += _check_lines(report)
    lines.append(f"  replay time {duration(report.wall_time_s)}")
    return "\n".join(lines)


def _where_lines(report: FlightReport) -> list[str]:
    """Where the flight went against the plan: insertion, landing, terminal state, entry."""
    km = 1.0 / M_PER_KM  # m -> km
    lines = []
    if report.insertion:
        i = report.insertion
        lines.append(
            f"  insertion vs plan: {number(i['position_difference_m'], 'm', 3)}, "
            f"{number(i['velocity_difference_mps'], 'm/s', 3)}, "
            f"{number(i['time_difference_s'], 's', 3)} "
            f"(altitude {number(i['altitude_difference_m'], 'm', 3)}, "
            f"speed {number(i['speed_difference_mps'], 'm/s', 3)})"
        )
    lines.append(
        f"  miss from the landing site: {number(_scaled(report.miss_distance_m, km), 'km')} "
        f"(stated {number(_scaled(report.stated_miss_m, km), 'km')}; plan predicted "
        f"{number(_scaled(report.predicted_miss_distance_m, km), 'km')})"
    )
    lines.append(
        f"  distance from the predicted terminal point: "
        f"{number(report.prediction_distance_m, 'm')} "
        f"(tolerance {number(report.prediction_tolerance_m, 'm')})"
    )
    if report.terminal:
        t = report.terminal
        lines.append(
            f"  terminal: {utc(t['epoch_utc'])}  {number(t['latitude_deg'], 'deg', 6)}, "
            f"{number(t['longitude_deg'], 'deg', 6)}, {number(t['altitude_m'] * km, 'km')}, "
            f"{number(t['speed_mps'], 'm/s')}, fpa {number(t['fpa_deg'], 'deg', 3)} "
            f"({report.terminal_status})"
        )
    if report.entry:
        e = report.entry
        lines.append(
            f"  entry: {utc(e['epoch_utc'])}  {number(e['latitude_deg'], 'deg', 6)}, "
            f"{number(e['longitude_deg'], 'deg', 6)}, {number(e['speed_mps'], 'm/s')} "
            f"relative, inertial fpa {number(e['inertial_fpa_deg'], 'deg')}; vs plan "
            f"{number(report.entry_time_difference_s, 's', 3)}, "
            f"{number(report.entry_position_difference_m, 'm', 3)}"
        )
    return lines


def _check_lines(report: FlightReport) -> list[str]:
    """The rendezvous arrival, each check against its limit and each burn as applied."""
    lines = [
        f"  rendezvous arrival miss: {number(report.rendezvous_arrival_miss_m, 'm', 3)} "
        f"(plan {number(report.planned_arrival_miss_m, 'm', 3)}, "
        f"tolerance {number(report.arrival_miss_tolerance_m, 'm')})"
    ]
    for name, check in report.checks.items():
        lines.append(
            f"  {'ok  ' if check.ok else 'FAIL'} {name}: "
            f"{number(check.value, check.unit.split(' ')[0], 6)} "
            f"(limit {number(check.limit, check.unit, 6)})"
        )
    for burn in report.burns:
        lines.append(
            f"  burn {burn.name}: {number(burn.dv_mps, 'm/s')} at {duration(burn.t_s)} "
            f"from the launch day's 0 h UTC (local frame vs plan "
            f"{number(burn.local_frame_difference_mps, 'm/s', 2)})"
        )
    return lines
