"""The launch stage's result: one flat row plus a trajectory table."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from ovtraj.astro.angles import wrap_to_two_pi
from ovtraj.astro.constants import EarthModel
from ovtraj.astro.elements import ClassicalElements
from ovtraj.astro.epoch import Epoch
from ovtraj.astro.frames import ecef_to_geocentric
from ovtraj.config.launch import DESIGN_VARIABLES
from ovtraj.launch.ascent_optimization import PhaseRecord
from ovtraj.launch.frame import launch_to_ecef
from ovtraj.store.records import BOOL, FLOAT, INT, TEXT, Column, RowColumns, plain

# The optimisation phases a result may record (ovtraj.launch.ascent_optimization.optimise_launch),
# each with the columns of _PHASE_COLUMNS in the row (prefix: the name, "-" as "_").
PHASES = ("genetic", "seed", "slsqp", "trust-constr")
LOSSES = ("gravity", "aero", "steering", "back_pressure")


def _deg(x: float | None) -> float | None:
    return None if x is None else math.degrees(x)


@dataclass(frozen=True)
class LaunchResult:
    """Maximum-payload ascent to the target orbit, timed on the launch day.

    Times are seconds from the launch day's 0 h UTC. Infeasible results keep what
    the stage reached; fields it never reached are ``None`` (never NaN).
    """

    feasible: bool
    reason: str | None
    target_altitude_m: float
    opportunity: str
    launch_day: Epoch
    payload_kg: float | None = None
    design: dict[str, float] = field(default_factory=dict)
    azimuth_rad: float | None = None
    drop_time_s: float | None = None
    insertion_time_s: float | None = None
    flight_time_s: float | None = None
    insertion_r_eci_m: np.ndarray | None = None
    insertion_v_eci_mps: np.ndarray | None = None
    insertion_latitude_rad: float | None = None
    insertion_longitude_rad: float | None = None
    osculating: ClassicalElements | None = None
    mean_inclination_rad: float | None = None
    mean_raan_rad: float | None = None
    mean_u_rad: float | None = None
    altitude_error_m: float | None = None
    speed_error_mps: float | None = None
    flight_path_angle_error_rad: float | None = None
    inclination_error_rad: float | None = None
    raan_error_rad: float | None = None
    max_dynamic_pressure_pa: float | None = None
    max_dynamic_pressure_time_s: float | None = None
    max_axial_load_g: float | None = None
    max_axial_load_time_s: float | None = None
    fairing_jettison_time_s: float | None = None
    ideal_delta_v_rocket_equation_mps: float | None = None
    ideal_delta_v_integrated_mps: float | None = None
    speed_gain_mps: float | None = None
    losses_mps: dict[str, float] = field(default_factory=dict)
    phases: list[PhaseRecord] = field(default_factory=list)
    trajectories: int = 0
    wall_time_s: float = 0.0
    trajectory: pd.DataFrame = field(default_factory=pd.DataFrame)

    @classmethod
    def infeasible(cls, inp: Any, reason: str) -> LaunchResult:
        return cls(
            feasible=False,
            reason=reason,
            target_altitude_m=inp.target_altitude_m,
            opportunity=inp.opportunity,
            launch_day=inp.launch_day,
        )

    @property
    def insertion_u_rad(self) -> float | None:
        """Osculating argument of latitude at insertion [rad], in [0, 2 pi)."""
        if self.osculating is None:
            return None
        return wrap_to_two_pi(self.osculating.argp + self.osculating.nu)

    @property
    def total_loss_mps(self) -> float | None:
        return sum(self.losses_mps.values()) if self.losses_mps else None

    def to_row(self) -> dict[str, Any]:
        """Flat, JSON- and Parquet-friendly record of :data:`ROW`; units named in the keys.
        A phase outside :data:`PHASES` (a solve to an insertion point's ``match``) adds
        its columns after them: that row is a cached solve's, not a grid table's."""
        row = ROW.row(self)
        for phase in self.phases:
            if phase.name not in PHASES:
                row.update({c.name: plain(c.get(self)) for c in _phase_columns(phase.name)})
        return row


def _epoch(day: Epoch, t: float | None) -> str | None:
    return None if t is None else day.plus_seconds(t).iso()


def _osculating(read: Callable[[ClassicalElements], float]) -> Callable[[LaunchResult], Any]:
    return lambda r: read(r.osculating) if r.osculating else None


def _component(vector: str, k: int) -> Callable[[LaunchResult], float | None]:
    """Component ``k`` of the array field ``vector`` (None without it)."""

    def get(r: LaunchResult) -> float | None:
        value = getattr(r, vector)
        return float(value[k]) if value is not None else None

    return get


def _phase(name: str) -> Callable[[LaunchResult], PhaseRecord | None]:
    """The record of the phase ``name`` (the last of that name), None if it did not run."""
    return lambda r: next((p for p in reversed(r.phases) if p.name == name), None)


_PHASE_COLUMNS = (
    ("payload_kg", FLOAT, "kg: the payload at the phase's end point", "payload_kg"),
    (
        "violation",
        FLOAT,
        "the largest scaled violation there (0: within tolerance)",
        "max_violation",
    ),
    ("residual", FLOAT, "the largest scaled |constraint| there (1: one tolerance)", "max_residual"),
    ("accepted", BOOL, "the phase's design replaced the incumbent", "accepted"),
    ("iterations", INT, "the optimiser's iterations", "iterations"),
    ("trajectories", INT, "ascents the phase flew", "trajectories"),
    ("time_s", FLOAT, "s: the phase's wall time (timing)", "wall_time_s"),
)


def _phase_columns(name: str) -> list[Column]:
    """The columns of the optimisation phase ``name`` (null when it did not run)."""
    phase = _phase(name)

    def value(attribute: str) -> Callable[[LaunchResult], Any]:
        return lambda r: getattr(phase(r), attribute) if phase(r) is not None else None

    key = name.replace("-", "_")
    return [
        Column(f"{key}_{suffix}", kind, f"{name} phase: {doc}", value(attribute))
        for suffix, kind, doc, attribute in _PHASE_COLUMNS
    ]


def _loss(name: str) -> Callable[[LaunchResult], float | None]:
    return lambda r: r.losses_mps.get(name)


def _design(name: str) -> Callable[[LaunchResult], float | None]:
    return lambda r: r.design.get(name)


ROW = RowColumns(
    [
        Column("feasible", BOOL, "the ascent met every limit", lambda r: r.feasible),
        Column("reason", TEXT, "why it is infeasible", lambda r: r.reason),
        Column(
            "target_altitude_km",
            FLOAT,
            "km: the circular orbit aimed at",
            lambda r: r.target_altitude_m / 1e3,
        ),
        Column(
            "opportunity",
            TEXT,
            "ascending or descending pass of the plane",
            lambda r: r.opportunity,
        ),
        Column(
            "launch_date_utc", TEXT, "YYYY-MM-DD: the launch day", lambda r: r.launch_day.iso()[:10]
        ),
        Column("payload_kg", FLOAT, "kg: the payload to orbit", lambda r: r.payload_kg),
        Column(
            "azimuth_deg",
            FLOAT,
            "deg from north: the launch azimuth",
            lambda r: _deg(r.azimuth_rad),
        ),
        Column(
            "drop_time_s",
            FLOAT,
            "s from the launch day's 0 h UTC: the drop",
            lambda r: r.drop_time_s,
        ),
        Column(
            "insertion_time_s",
            FLOAT,
            "s from the launch day's 0 h UTC: the insertion",
            lambda r: r.insertion_time_s,
        ),
        Column("flight_time_s", FLOAT, "s: the drop to the insertion", lambda r: r.flight_time_s),
        Column(
            "drop_epoch_utc",
            TEXT,
            "ISO UTC of the drop",
            lambda r: _epoch(r.launch_day, r.drop_time_s),
        ),
        Column(
            "insertion_epoch_utc",
            TEXT,
            "ISO UTC of the insertion",
            lambda r: _epoch(r.launch_day, r.insertion_time_s),
        ),
        Column(
            "insertion_u_deg",
            FLOAT,
            "deg: osculating argument of latitude at insertion, [0, 360)",
            lambda r: _deg(r.insertion_u_rad),
        ),
        Column(
            "insertion_mean_u_deg",
            FLOAT,
            "deg: J2 mean argument of latitude at insertion",
            lambda r: _deg(r.mean_u_rad),
        ),
        Column(
            "insertion_latitude_deg",
            FLOAT,
            "deg: geocentric latitude at insertion",
            lambda r: _deg(r.insertion_latitude_rad),
        ),
        Column(
            "insertion_longitude_deg",
            FLOAT,
            "deg: longitude at insertion",
            lambda r: _deg(r.insertion_longitude_rad),
        ),
        Column(
            "insertion_altitude_error_m",
            FLOAT,
            "m: radius at insertion minus the target orbit's",
            lambda r: r.altitude_error_m,
        ),
        Column(
            "insertion_speed_error_mps",
            FLOAT,
            "m/s: speed at insertion minus the circular speed",
            lambda r: r.speed_error_mps,
        ),
        Column(
            "insertion_fpa_error_deg",
            FLOAT,
            "deg: inertial flight-path angle at insertion (0 aimed at)",
            lambda r: _deg(r.flight_path_angle_error_rad),
        ),
        Column(
            "inclination_error_deg",
            FLOAT,
            "deg: mean inclination minus the target plane's",
            lambda r: _deg(r.inclination_error_rad),
        ),
        Column(
            "raan_error_deg",
            FLOAT,
            "deg: node from the target plane's",
            lambda r: _deg(r.raan_error_rad),
        ),
        Column(
            "semi_major_axis_km",
            FLOAT,
            "km: osculating semi-major axis at insertion",
            _osculating(lambda osc: osc.a / 1e3),
        ),
        Column(
            "eccentricity",
            FLOAT,
            "osculating eccentricity at insertion",
            _osculating(lambda osc: osc.e),
        ),
        Column(
            "inclination_deg",
            FLOAT,
            "deg: osculating inclination at insertion",
            _osculating(lambda osc: _deg(osc.i)),
        ),
        Column(
            "raan_deg",
            FLOAT,
            "deg: osculating node at insertion, [0, 360)",
            _osculating(lambda osc: _deg(wrap_to_two_pi(osc.raan))),
        ),
        Column(
            "mean_inclination_deg",
            FLOAT,
            "deg: J2 mean inclination at insertion",
            lambda r: _deg(r.mean_inclination_rad),
        ),
        Column(
            "mean_raan_deg",
            FLOAT,
            "deg: J2 mean node at insertion",
            lambda r: _deg(r.mean_raan_rad),
        ),
        Column(
            "max_dynamic_pressure_pa",
            FLOAT,
            "Pa: the peak dynamic pressure",
            lambda r: r.max_dynamic_pressure_pa,
        ),
        Column(
            "max_dynamic_pressure_time_s",
            FLOAT,
            "s from the drop: at the peak",
            lambda r: r.max_dynamic_pressure_time_s,
        ),
        Column("max_axial_load_g", FLOAT, "g: the peak axial load", lambda r: r.max_axial_load_g),
        Column(
            "max_axial_load_time_s",
            FLOAT,
            "s from the drop: at the peak",
            lambda r: r.max_axial_load_time_s,
        ),
        Column(
            "fairing_jettison_time_s",
            FLOAT,
            "s from the drop: the fairing dropped",
            lambda r: r.fairing_jettison_time_s,
        ),
        Column(
            "ideal_dv_rocket_equation_mps",
            FLOAT,
            "m/s: the stages' ideal speed by the rocket equation",
            lambda r: r.ideal_delta_v_rocket_equation_mps,
        ),
        Column(
            "ideal_dv_integrated_mps",
            FLOAT,
            "m/s: the same, integrated along the ascent",
            lambda r: r.ideal_delta_v_integrated_mps,
        ),
        Column(
            "speed_gain_mps",
            FLOAT,
            "m/s: inertial speed at insertion minus at the drop",
            lambda r: r.speed_gain_mps,
        ),
        Column("total_loss_mps", FLOAT, "m/s: the sum of the losses", lambda r: r.total_loss_mps),
        Column("trajectories", INT, "ascents flown by the solve", lambda r: r.trajectories),
        Column("wall_time_s", FLOAT, "s: the solve's wall time (timing)", lambda r: r.wall_time_s),
        *[
            Column(
                f"{name}_loss_mps", FLOAT, f"m/s: the {name.replace('_', ' ')} loss", _loss(name)
            )
            for name in LOSSES
        ],
        *[
            Column(
                f"design_{name}", FLOAT, "the design variable (configuration units)", _design(name)
            )
            for name in DESIGN_VARIABLES
        ],
        *[
            Column(
                f"insertion_{kind}_eci_{axis}_{unit}",
                FLOAT,
                f"{symbol}: the insertion {what}, ECI {axis}",
                _component(f"insertion_{kind}_eci_{unit}", k),
            )
            for k, axis in enumerate("xyz")
            for kind, unit, symbol, what in (
                ("r", "m", "m", "position"),
                ("v", "mps", "m/s", "velocity"),
            )
        ],
        *[column for phase in PHASES for column in _phase_columns(phase)],
    ],
    required=("feasible", "target_altitude_km"),
)
"""The launch stage's row (:meth:`LaunchResult.to_row`)."""

ROW_SCHEMA = ROW.schema
"""The columns of :meth:`LaunchResult.to_row` (a phase the solve did not run is null)."""


def trajectory_table(
    history: list[dict[str, Any]],
    *,
    row: int,
    axes: np.ndarray,
    earth: EarthModel,
    drop_time_s: float,
    step_s: float,
) -> pd.DataFrame:
    """Samples of one design's ascent, about every ``step_s`` plus each phase's ends."""
    keep: list[dict[str, Any]] = []
    last_t = -math.inf
    for k, sample in enumerate(history):
        t = float(sample["t"][row])
        boundary = k == 0 or k == len(history) - 1 or sample["phase"] != history[k - 1]["phase"]
        if boundary or (k + 1 < len(history) and history[k + 1]["phase"] != sample["phase"]):
            keep.append(sample)
            last_t = t
        elif t - last_t >= step_s - 1e-9:
            keep.append(sample)
            last_t = t
    y = np.stack([s["y"][:, row] for s in keep])
    r_ecef, v_ecef = launch_to_ecef(y[:, 0:3], y[:, 3:6], axes, radius_m=earth.radius)
    lat, lon, alt = ecef_to_geocentric(r_ecef, radius=earth.radius)
    speed = np.linalg.norm(v_ecef, axis=1)
    up = r_ecef / np.linalg.norm(r_ecef, axis=1, keepdims=True)
    fpa = np.arcsin(np.clip(np.einsum("ij,ij->i", up, v_ecef) / speed, -1.0, 1.0))
    v_inertial = v_ecef + np.cross([0.0, 0.0, earth.omega], r_ecef)
    t = np.array([float(s["t"][row]) for s in keep])
    return pd.DataFrame(
        {
            "time_s": t,
            "time_from_0h_s": t + drop_time_s,
            "phase": [s["phase"] for s in keep],
            "stage": [int(s["stage"]) + 1 for s in keep],
            "altitude_m": alt,
            "latitude_deg": np.degrees(lat),
            "longitude_deg": np.degrees(lon),
            "speed_mps": speed,
            "inertial_speed_mps": np.linalg.norm(v_inertial, axis=1),
            "flight_path_angle_deg": np.degrees(fpa),
            "mass_kg": y[:, 6],
            "alpha_deg": np.degrees([float(s["alpha_rad"][row]) for s in keep]),
            "mach": [float(s["mach"][row]) for s in keep],
            "dynamic_pressure_pa": [float(s["dynamic_pressure_pa"][row]) for s in keep],
            "axial_load_g": [float(s["axial_load_g"][row]) for s in keep],
            "thrust_n": [float(s["thrust_n"][row]) for s in keep],
        }
    )
