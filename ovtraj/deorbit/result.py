"""The deorbit stage's result: a flat row for the run store and a trajectory table."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from ovtraj.astro.epoch import Epoch
from ovtraj.deorbit.correction import CONSTRAINT_NAMES
from ovtraj.store.records import BOOL, FLOAT, INT, TEXT, plain, record_schema


def _deg(x: float | None) -> float | None:
    return None if x is None else math.degrees(x)


@dataclass(frozen=True)
class DeorbitResult:
    """Burn and entry state; times in s from the input epoch, angles in rad (SI).

    Infeasible results keep what the stage reached; fields it never reached are
    ``None`` (never NaN).
    """

    feasible: bool
    reason: str | None
    epoch: Epoch
    burn_t_s: float | None = None
    dv_eci_mps: np.ndarray | None = None
    dv_rsw_mps: np.ndarray | None = None
    entry_t_s: float | None = None
    entry_r_eci_m: np.ndarray | None = None
    entry_v_eci_mps: np.ndarray | None = None
    entry_latitude_rad: float | None = None
    entry_longitude_rad: float | None = None
    entry_altitude_m: float | None = None
    entry_speed_mps: float | None = None  # inertial
    entry_fpa_rad: float | None = None  # inertial
    entry_relative_speed_mps: float | None = None
    entry_relative_fpa_rad: float | None = None
    entry_heading_rad: float | None = None  # of the Earth-relative velocity, from north
    entry_error_m: float | None = None  # great-circle distance from the entry point
    virtual_entry_t_s: float | None = None
    virtual_entry_latitude_rad: float | None = None
    virtual_entry_longitude_rad: float | None = None
    estimate_dv_mps: float | None = None  # two-body tangential impulse
    estimate_central_angle_rad: float | None = None
    estimate_time_of_flight_s: float | None = None
    iterations: int = 0
    solver_message: str = ""
    constraints: dict[str, float] = field(default_factory=dict)
    passes_in_region: int = 0
    passes_tried: int = 0
    propagations: int = 0
    wall_time_s: float = 0.0
    trajectory: pd.DataFrame = field(default_factory=pd.DataFrame)

    @property
    def dv_mps(self) -> float | None:
        return None if self.dv_eci_mps is None else float(np.linalg.norm(self.dv_eci_mps))

    @property
    def wait_time_s(self) -> float | None:
        return self.burn_t_s  # the stage starts at the input epoch

    @property
    def descent_time_s(self) -> float | None:
        if self.burn_t_s is None or self.entry_t_s is None:
            return None
        return self.entry_t_s - self.burn_t_s

    def to_row(self) -> dict[str, Any]:
        """Flat, JSON- and Parquet-friendly record; units named in the keys."""
        row: dict[str, Any] = {
            "feasible": self.feasible,
            "reason": self.reason,
            "epoch_utc": self.epoch.iso(),
            "burn_epoch_utc": _epoch(self.epoch, self.burn_t_s),
            "burn_time_s": self.burn_t_s,
            "wait_time_s": self.wait_time_s,
            "dv_mps": self.dv_mps,
            "descent_time_s": self.descent_time_s,
            "entry_epoch_utc": _epoch(self.epoch, self.entry_t_s),
            "entry_time_s": self.entry_t_s,
            "entry_lat_deg": _deg(self.entry_latitude_rad),
            "entry_lon_deg": _deg(self.entry_longitude_rad),
            "entry_altitude_km": _km(self.entry_altitude_m),
            "entry_speed_mps": self.entry_speed_mps,
            "entry_fpa_deg": _deg(self.entry_fpa_rad),
            "entry_relative_speed_mps": self.entry_relative_speed_mps,
            "entry_relative_fpa_deg": _deg(self.entry_relative_fpa_rad),
            "entry_heading_deg": _deg(self.entry_heading_rad),
            "entry_error_km": _km(self.entry_error_m),
            "virtual_entry_epoch_utc": _epoch(self.epoch, self.virtual_entry_t_s),
            "virtual_entry_lat_deg": _deg(self.virtual_entry_latitude_rad),
            "virtual_entry_lon_deg": _deg(self.virtual_entry_longitude_rad),
            "estimate_dv_mps": self.estimate_dv_mps,
            "estimate_central_angle_deg": _deg(self.estimate_central_angle_rad),
            "estimate_time_of_flight_s": self.estimate_time_of_flight_s,
            "iterations": self.iterations,
            "solver_message": self.solver_message,
            "passes_in_region": self.passes_in_region,
            "passes_tried": self.passes_tried,
            "propagations": self.propagations,
            "wall_time_s": self.wall_time_s,
        }
        for axis, k in zip("xyz", range(3), strict=True):
            dv = self.dv_eci_mps
            row[f"dv_eci_{axis}_mps"] = float(dv[k]) if dv is not None else None
            r, v = self.entry_r_eci_m, self.entry_v_eci_mps
            row[f"entry_r_eci_{axis}_m"] = float(r[k]) if r is not None else None
            row[f"entry_v_eci_{axis}_mps"] = float(v[k]) if v is not None else None
        for name, k in (("radial", 0), ("along_track", 1), ("cross_track", 2)):
            dv = self.dv_rsw_mps
            row[f"dv_{name}_mps"] = float(dv[k]) if dv is not None else None
        for name in CONSTRAINT_NAMES:
            row[f"constraint_{name}"] = self.constraints.get(name)
        return {k: plain(v) for k, v in row.items()}


_RSW = ("radial", "along_track", "cross_track")

ROW_SCHEMA = record_schema(
    [
        ("feasible", BOOL),
        ("reason", TEXT),
        ("epoch_utc", TEXT),
        ("burn_epoch_utc", TEXT),
        ("burn_time_s", FLOAT),
        ("wait_time_s", FLOAT),
        ("dv_mps", FLOAT),
        ("descent_time_s", FLOAT),
        ("entry_epoch_utc", TEXT),
        ("entry_time_s", FLOAT),
        ("entry_lat_deg", FLOAT),
        ("entry_lon_deg", FLOAT),
        ("entry_altitude_km", FLOAT),
        ("entry_speed_mps", FLOAT),
        ("entry_fpa_deg", FLOAT),
        ("entry_relative_speed_mps", FLOAT),
        ("entry_relative_fpa_deg", FLOAT),
        ("entry_heading_deg", FLOAT),
        ("entry_error_km", FLOAT),
        ("virtual_entry_epoch_utc", TEXT),
        ("virtual_entry_lat_deg", FLOAT),
        ("virtual_entry_lon_deg", FLOAT),
        ("estimate_dv_mps", FLOAT),
        ("estimate_central_angle_deg", FLOAT),
        ("estimate_time_of_flight_s", FLOAT),
        ("iterations", INT),
        ("solver_message", TEXT),
        ("passes_in_region", INT),
        ("passes_tried", INT),
        ("propagations", INT),
        ("wall_time_s", FLOAT),
        *[
            (f"{vector}_{axis}{unit}", FLOAT)
            for axis in "xyz"
            for vector, unit in (("dv_eci", "_mps"), ("entry_r_eci", "_m"), ("entry_v_eci", "_mps"))
        ],
        *[(f"dv_{axis}_mps", FLOAT) for axis in _RSW],
        *[(f"constraint_{name}", FLOAT) for name in CONSTRAINT_NAMES],
    ],
    required=("feasible",),
)
"""The columns of :meth:`DeorbitResult.to_row` (``wall_time_s`` is timing, not a result)."""

TRAJECTORY_SCHEMA = record_schema(
    [
        ("time_s", FLOAT),
        ("phase", TEXT),
        *[(name, FLOAT) for name in ("x_m", "y_m", "z_m", "vx_mps", "vy_mps", "vz_mps")],
        *[
            (name, FLOAT)
            for name in ("altitude_km", "latitude_deg", "longitude_deg", "speed_mps", "fpa_deg")
        ],
    ],
)
"""The columns of :attr:`DeorbitResult.trajectory`."""


def _km(x: float | None) -> float | None:
    return None if x is None else x / 1e3


def _epoch(day: Epoch, t: float | None) -> str | None:
    return None if t is None else day.plus_seconds(t).iso()
