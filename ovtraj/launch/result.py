"""The launch stage's result: one flat row plus a trajectory table."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from ovtraj.astro.angles import TWO_PI
from ovtraj.astro.constants import EarthModel
from ovtraj.astro.elements import ClassicalElements
from ovtraj.astro.epoch import Epoch
from ovtraj.astro.frames import ecef_to_geocentric
from ovtraj.config.launch import DESIGN_VARIABLES
from ovtraj.launch.ascent_optimization import PhaseRecord
from ovtraj.launch.frame import launch_to_ecef
from ovtraj.store.records import BOOL, FLOAT, INT, TEXT, plain, record_schema

# The optimisation phases a result may record (ovtraj.launch.ascent_optimization.optimise_launch),
# each with the columns of PHASE_COLUMNS in the row (prefix: the name, "-" as "_").
PHASES = ("genetic", "seed", "slsqp", "trust-constr")
PHASE_COLUMNS = (
    ("payload_kg", FLOAT),
    ("violation", FLOAT),
    ("residual", FLOAT),
    ("accepted", BOOL),
    ("iterations", INT),
    ("trajectories", INT),
    ("time_s", FLOAT),
)
LOSSES = ("gravity", "aero", "steering", "back_pressure")

ROW_SCHEMA = record_schema(
    [
        ("feasible", BOOL),
        ("reason", TEXT),
        ("target_altitude_km", FLOAT),
        ("opportunity", TEXT),
        ("launch_date_utc", TEXT),
        *[
            (name, FLOAT)
            for name in (
                "payload_kg",
                "azimuth_deg",
                "drop_time_s",
                "insertion_time_s",
                "flight_time_s",
            )
        ],
        ("drop_epoch_utc", TEXT),
        ("insertion_epoch_utc", TEXT),
        *[
            (name, FLOAT)
            for name in (
                "insertion_u_deg",
                "insertion_mean_u_deg",
                "insertion_latitude_deg",
                "insertion_longitude_deg",
                "insertion_altitude_error_m",
                "insertion_speed_error_mps",
                "insertion_fpa_error_deg",
                "inclination_error_deg",
                "raan_error_deg",
                "semi_major_axis_km",
                "eccentricity",
                "inclination_deg",
                "raan_deg",
                "mean_inclination_deg",
                "mean_raan_deg",
                "max_dynamic_pressure_pa",
                "max_dynamic_pressure_time_s",
                "max_axial_load_g",
                "max_axial_load_time_s",
                "fairing_jettison_time_s",
                "ideal_dv_rocket_equation_mps",
                "ideal_dv_integrated_mps",
                "speed_gain_mps",
                "total_loss_mps",
            )
        ],
        ("trajectories", INT),
        ("wall_time_s", FLOAT),
        *[(f"{name}_loss_mps", FLOAT) for name in LOSSES],
        *[(f"design_{name}", FLOAT) for name in DESIGN_VARIABLES],
        *[
            (f"insertion_{kind}_eci_{axis}_{unit}", FLOAT)
            for axis in "xyz"
            for kind, unit in (("r", "m"), ("v", "mps"))
        ],
        *[
            (f"{phase.replace('-', '_')}_{column}", kind)
            for phase in PHASES
            for column, kind in PHASE_COLUMNS
        ],
    ],
    required=("feasible", "target_altitude_km"),
)
"""The columns of :meth:`LaunchResult.to_row` (a phase the solve did not run is null)."""


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
        return (self.osculating.argp + self.osculating.nu) % TWO_PI

    @property
    def total_loss_mps(self) -> float | None:
        return sum(self.losses_mps.values()) if self.losses_mps else None

    def to_row(self) -> dict[str, Any]:
        """Flat, JSON- and Parquet-friendly record; units named in the keys."""
        osc = self.osculating
        row: dict[str, Any] = {
            "feasible": self.feasible,
            "reason": self.reason,
            "target_altitude_km": self.target_altitude_m / 1e3,
            "opportunity": self.opportunity,
            "launch_date_utc": self.launch_day.iso()[:10],
            "payload_kg": self.payload_kg,
            "azimuth_deg": _deg(self.azimuth_rad),
            "drop_time_s": self.drop_time_s,
            "insertion_time_s": self.insertion_time_s,
            "flight_time_s": self.flight_time_s,
            "drop_epoch_utc": _epoch(self.launch_day, self.drop_time_s),
            "insertion_epoch_utc": _epoch(self.launch_day, self.insertion_time_s),
            "insertion_u_deg": _deg(self.insertion_u_rad),
            "insertion_mean_u_deg": _deg(self.mean_u_rad),
            "insertion_latitude_deg": _deg(self.insertion_latitude_rad),
            "insertion_longitude_deg": _deg(self.insertion_longitude_rad),
            "insertion_altitude_error_m": self.altitude_error_m,
            "insertion_speed_error_mps": self.speed_error_mps,
            "insertion_fpa_error_deg": _deg(self.flight_path_angle_error_rad),
            "inclination_error_deg": _deg(self.inclination_error_rad),
            "raan_error_deg": _deg(self.raan_error_rad),
            "semi_major_axis_km": osc.a / 1e3 if osc else None,
            "eccentricity": osc.e if osc else None,
            "inclination_deg": _deg(osc.i) if osc else None,
            "raan_deg": _deg(osc.raan % TWO_PI) if osc else None,
            "mean_inclination_deg": _deg(self.mean_inclination_rad),
            "mean_raan_deg": _deg(self.mean_raan_rad),
            "max_dynamic_pressure_pa": self.max_dynamic_pressure_pa,
            "max_dynamic_pressure_time_s": self.max_dynamic_pressure_time_s,
            "max_axial_load_g": self.max_axial_load_g,
            "max_axial_load_time_s": self.max_axial_load_time_s,
            "fairing_jettison_time_s": self.fairing_jettison_time_s,
            "ideal_dv_rocket_equation_mps": self.ideal_delta_v_rocket_equation_mps,
            "ideal_dv_integrated_mps": self.ideal_delta_v_integrated_mps,
            "speed_gain_mps": self.speed_gain_mps,
            "total_loss_mps": self.total_loss_mps,
            "trajectories": self.trajectories,
            "wall_time_s": self.wall_time_s,
        }
        for name in LOSSES:
            row[f"{name}_loss_mps"] = self.losses_mps.get(name)
        for name, value in self.design.items():
            row[f"design_{name}"] = value
        for axis, k in zip("xyz", range(3), strict=True):
            r, v = self.insertion_r_eci_m, self.insertion_v_eci_mps
            row[f"insertion_r_eci_{axis}_m"] = float(r[k]) if r is not None else None
            row[f"insertion_v_eci_{axis}_mps"] = float(v[k]) if v is not None else None
        for phase in self.phases:
            key = phase.name.replace("-", "_")
            row[f"{key}_payload_kg"] = phase.payload_kg
            row[f"{key}_violation"] = phase.max_violation
            row[f"{key}_residual"] = phase.max_residual
            row[f"{key}_accepted"] = phase.accepted
            row[f"{key}_iterations"] = phase.iterations
            row[f"{key}_trajectories"] = phase.trajectories
            row[f"{key}_time_s"] = phase.wall_time_s
        return plain(row)


def _epoch(day: Epoch, t: float | None) -> str | None:
    return None if t is None else day.plus_seconds(t).iso()


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
