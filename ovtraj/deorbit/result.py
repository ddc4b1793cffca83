"""The deorbit stage's result: a flat row for the run store and a trajectory table."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from ovtraj.astro.epoch import Epoch
from ovtraj.deorbit.correction import CONSTRAINT_NAMES
from ovtraj.store.records import BOOL, FLOAT, INT, TEXT, Column, RowColumns, record_schema


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
        """Flat, JSON- and Parquet-friendly record of :data:`ROW`; units named in the keys."""
        return ROW.row(self)


_RSW = ("radial", "along_track", "cross_track")


def _component(vector: str, k: int) -> Callable[[DeorbitResult], float | None]:
    """Component ``k`` of the array field ``vector`` (None without it)."""

    def get(r: DeorbitResult) -> float | None:
        value = getattr(r, vector)
        return float(value[k]) if value is not None else None

    return get


def _constraint(name: str) -> Callable[[DeorbitResult], float | None]:
    return lambda r: r.constraints.get(name)


_VECTORS = (
    ("dv_eci", "_mps", "dv_eci_mps", "m/s: the impulse, ECI"),
    ("entry_r_eci", "_m", "entry_r_eci_m", "m: the position at the entry interface, ECI"),
    ("entry_v_eci", "_mps", "entry_v_eci_mps", "m/s: the velocity at the entry interface, ECI"),
)

ROW = RowColumns(
    [
        Column("feasible", BOOL, "the stage met every limit", lambda r: r.feasible),
        Column("reason", TEXT, "why it is infeasible", lambda r: r.reason),
        Column(
            "epoch_utc",
            TEXT,
            "ISO UTC: the stage's start, the times' origin",
            lambda r: r.epoch.iso(),
        ),
        Column(
            "burn_epoch_utc", TEXT, "ISO UTC of the burn", lambda r: _epoch(r.epoch, r.burn_t_s)
        ),
        Column("burn_time_s", FLOAT, "s from epoch_utc: the burn", lambda r: r.burn_t_s),
        Column("wait_time_s", FLOAT, "s: the start to the burn", lambda r: r.wait_time_s),
        Column("dv_mps", FLOAT, "m/s: the impulse", lambda r: r.dv_mps),
        Column(
            "descent_time_s",
            FLOAT,
            "s: the burn to the entry interface",
            lambda r: r.descent_time_s,
        ),
        Column(
            "entry_epoch_utc",
            TEXT,
            "ISO UTC at the entry interface",
            lambda r: _epoch(r.epoch, r.entry_t_s),
        ),
        Column(
            "entry_time_s", FLOAT, "s from epoch_utc: the entry interface", lambda r: r.entry_t_s
        ),
        Column(
            "entry_lat_deg",
            FLOAT,
            "deg: the entry point's latitude",
            lambda r: _deg(r.entry_latitude_rad),
        ),
        Column(
            "entry_lon_deg",
            FLOAT,
            "deg: the entry point's longitude",
            lambda r: _deg(r.entry_longitude_rad),
        ),
        Column(
            "entry_altitude_km",
            FLOAT,
            "km: the entry interface's altitude",
            lambda r: _km(r.entry_altitude_m),
        ),
        Column(
            "entry_speed_mps", FLOAT, "m/s: inertial speed at entry", lambda r: r.entry_speed_mps
        ),
        Column(
            "entry_fpa_deg",
            FLOAT,
            "deg: inertial flight-path angle at entry",
            lambda r: _deg(r.entry_fpa_rad),
        ),
        Column(
            "entry_relative_speed_mps",
            FLOAT,
            "m/s: Earth-relative speed at entry",
            lambda r: r.entry_relative_speed_mps,
        ),
        Column(
            "entry_relative_fpa_deg",
            FLOAT,
            "deg: Earth-relative flight-path angle at entry",
            lambda r: _deg(r.entry_relative_fpa_rad),
        ),
        Column(
            "entry_heading_deg",
            FLOAT,
            "deg from north: the Earth-relative velocity's heading at entry",
            lambda r: _deg(r.entry_heading_rad),
        ),
        Column(
            "entry_error_km",
            FLOAT,
            "km: great-circle distance from the configured entry point",
            lambda r: _km(r.entry_error_m),
        ),
        Column(
            "virtual_entry_epoch_utc",
            TEXT,
            "ISO UTC of the pass the burn aims at (the virtual entry)",
            lambda r: _epoch(r.epoch, r.virtual_entry_t_s),
        ),
        Column(
            "virtual_entry_lat_deg",
            FLOAT,
            "deg: the virtual entry's latitude",
            lambda r: _deg(r.virtual_entry_latitude_rad),
        ),
        Column(
            "virtual_entry_lon_deg",
            FLOAT,
            "deg: the virtual entry's longitude",
            lambda r: _deg(r.virtual_entry_longitude_rad),
        ),
        Column(
            "estimate_dv_mps",
            FLOAT,
            "m/s: the two-body tangential impulse estimate",
            lambda r: r.estimate_dv_mps,
        ),
        Column(
            "estimate_central_angle_deg",
            FLOAT,
            "deg: the estimate's central angle from the burn to entry",
            lambda r: _deg(r.estimate_central_angle_rad),
        ),
        Column(
            "estimate_time_of_flight_s",
            FLOAT,
            "s: the estimate's burn to entry",
            lambda r: r.estimate_time_of_flight_s,
        ),
        Column("iterations", INT, "the correction's iterations", lambda r: r.iterations),
        Column("solver_message", TEXT, "the correction's last word", lambda r: r.solver_message),
        Column(
            "passes_in_region",
            INT,
            "passes over the entry region within the horizon",
            lambda r: r.passes_in_region,
        ),
        Column("passes_tried", INT, "passes the correction was run on", lambda r: r.passes_tried),
        Column("propagations", INT, "orbit propagations of the stage", lambda r: r.propagations),
        Column(
            "wall_time_s",
            FLOAT,
            "s: the stage's wall time (timing, not a result)",
            lambda r: r.wall_time_s,
        ),
        *[
            Column(f"{vector}_{axis}{unit}", FLOAT, f"{doc} {axis}", _component(field_name, k))
            for k, axis in enumerate("xyz")
            for vector, unit, field_name, doc in _VECTORS
        ],
        *[
            Column(
                f"dv_{axis}_mps",
                FLOAT,
                f"m/s: the impulse, {axis.replace('_', '-')} (RSW)",
                _component("dv_rsw_mps", k),
            )
            for k, axis in enumerate(_RSW)
        ],
        *[
            Column(
                f"constraint_{name}",
                FLOAT,
                "the correction's final constraint value (>= 0 met; degrees or scaled speed)",
                _constraint(name),
            )
            for name in CONSTRAINT_NAMES
        ],
    ],
    required=("feasible",),
)
"""The deorbit stage's row (:meth:`DeorbitResult.to_row`)."""

ROW_SCHEMA = ROW.schema
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
