"""The reentry stage's result: a flat row for the run store and a trajectory table."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import pandas as pd

from ovtraj.astro.epoch import Epoch
from ovtraj.store.records import BOOL, FLOAT, INT, TEXT, Column, RowColumns, record_schema


def _deg(x: float | None) -> float | None:
    return None if x is None else math.degrees(x)


def _scaled(x: float | None, factor: float) -> float | None:
    return None if x is None else x * factor


@dataclass(frozen=True)
class ReentryResult:
    """Guided entry to the terminal interface; SI, times from the entry epoch."""

    feasible: bool
    reason: str | None
    epoch: Epoch
    flags: tuple[str, ...] = ()
    miss_distance_m: float | None = None
    flight_time_s: float | None = None
    terminal_altitude_m: float | None = None
    terminal_speed_mps: float | None = None
    terminal_latitude_rad: float | None = None
    terminal_longitude_rad: float | None = None
    terminal_fpa_rad: float | None = None
    terminal_heading_rad: float | None = None
    max_heat_rate_w_m2: float | None = None
    max_heat_rate_time_s: float | None = None
    max_load_g: float | None = None
    max_load_time_s: float | None = None
    max_dynamic_pressure_pa: float | None = None
    max_dynamic_pressure_time_s: float | None = None
    max_bank_rad: float | None = None
    heat_rate_margin: float | None = None  # 1 - max / limit
    load_margin: float | None = None
    dynamic_pressure_margin: float | None = None
    bank_margin: float | None = None
    sigma0_rad: float | None = None
    sigma1_rad: float | None = None
    reversals: int = 0
    newton_iterations: int = 0
    golden_evaluations: int = 0
    trajectories: int = 0
    wall_time_s: float = 0.0
    trajectory: pd.DataFrame = field(default_factory=pd.DataFrame)

    def to_row(self) -> dict[str, Any]:
        """Flat, JSON- and Parquet-friendly record of :data:`ROW`; units named in the keys."""
        return ROW.row(self)


def _terminal_epoch(r: ReentryResult) -> str | None:
    return None if r.flight_time_s is None else r.epoch.plus_seconds(r.flight_time_s).iso()


ROW = RowColumns(
    [
        Column("feasible", BOOL, "the entry met every limit", lambda r: r.feasible),
        Column("reason", TEXT, "why it is infeasible", lambda r: r.reason),
        Column(
            "flags",
            TEXT,
            "what stopped the guidance short (time_limit, iteration_limit...), ';'-separated",
            lambda r: ";".join(r.flags),
        ),
        Column(
            "entry_epoch_utc",
            TEXT,
            "ISO UTC at the entry interface, the times' origin",
            lambda r: r.epoch.iso(),
        ),
        Column(
            "miss_distance_km",
            FLOAT,
            "km: the terminal point from the landing site",
            lambda r: _scaled(r.miss_distance_m, 1e-3),
        ),
        Column(
            "flight_time_s", FLOAT, "s: entry to the terminal interface", lambda r: r.flight_time_s
        ),
        Column("terminal_epoch_utc", TEXT, "ISO UTC at the terminal interface", _terminal_epoch),
        Column(
            "terminal_altitude_km",
            FLOAT,
            "km: altitude at the terminal interface",
            lambda r: _scaled(r.terminal_altitude_m, 1e-3),
        ),
        Column(
            "terminal_speed_mps",
            FLOAT,
            "m/s: Earth-relative speed there",
            lambda r: r.terminal_speed_mps,
        ),
        Column(
            "terminal_lat_deg",
            FLOAT,
            "deg: latitude there",
            lambda r: _deg(r.terminal_latitude_rad),
        ),
        Column(
            "terminal_lon_deg",
            FLOAT,
            "deg: longitude there",
            lambda r: _deg(r.terminal_longitude_rad),
        ),
        Column(
            "terminal_fpa_deg",
            FLOAT,
            "deg: flight-path angle there",
            lambda r: _deg(r.terminal_fpa_rad),
        ),
        Column(
            "terminal_heading_deg",
            FLOAT,
            "deg from north: heading there",
            lambda r: _deg(r.terminal_heading_rad),
        ),
        Column(
            "max_heat_rate_kw_m2",
            FLOAT,
            "kW/m^2: the peak stagnation heat rate",
            lambda r: _scaled(r.max_heat_rate_w_m2, 1e-3),
        ),
        Column(
            "max_heat_rate_time_s",
            FLOAT,
            "s from entry: at the peak",
            lambda r: r.max_heat_rate_time_s,
        ),
        Column("max_load_g", FLOAT, "g: the peak load factor", lambda r: r.max_load_g),
        Column("max_load_time_s", FLOAT, "s from entry: at the peak", lambda r: r.max_load_time_s),
        Column(
            "max_dynamic_pressure_kpa",
            FLOAT,
            "kPa: the peak dynamic pressure",
            lambda r: _scaled(r.max_dynamic_pressure_pa, 1e-3),
        ),
        Column(
            "max_dynamic_pressure_time_s",
            FLOAT,
            "s from entry: at the peak",
            lambda r: r.max_dynamic_pressure_time_s,
        ),
        Column(
            "max_bank_deg",
            FLOAT,
            "deg: the largest bank angle flown",
            lambda r: _deg(r.max_bank_rad),
        ),
        Column("heat_rate_margin", FLOAT, "1 - peak / limit", lambda r: r.heat_rate_margin),
        Column("load_margin", FLOAT, "1 - peak / limit", lambda r: r.load_margin),
        Column(
            "dynamic_pressure_margin",
            FLOAT,
            "1 - peak / limit",
            lambda r: r.dynamic_pressure_margin,
        ),
        Column("bank_margin", FLOAT, "1 - largest / limit", lambda r: r.bank_margin),
        Column(
            "sigma0_deg",
            FLOAT,
            "deg: the bank profile's magnitude at entry",
            lambda r: _deg(r.sigma0_rad),
        ),
        Column(
            "sigma1_deg",
            FLOAT,
            "deg: the bank profile's magnitude at the terminal speed",
            lambda r: _deg(r.sigma1_rad),
        ),
        Column("reversals", INT, "bank reversals flown", lambda r: r.reversals),
        Column(
            "newton_iterations",
            INT,
            "Newton steps on sigma0 (range)",
            lambda r: r.newton_iterations,
        ),
        Column(
            "golden_evaluations",
            INT,
            "golden-section evaluations on sigma1 (miss)",
            lambda r: r.golden_evaluations,
        ),
        Column("trajectories", INT, "entries flown by the guidance", lambda r: r.trajectories),
        Column(
            "wall_time_s",
            FLOAT,
            "s: the stage's wall time (timing, not a result)",
            lambda r: r.wall_time_s,
        ),
    ],
    required=("feasible",),
)
"""The reentry stage's row (:meth:`ReentryResult.to_row`)."""

ROW_SCHEMA = ROW.schema
"""The columns of :meth:`ReentryResult.to_row` (``wall_time_s`` is timing, not a result)."""

TRAJECTORY_SCHEMA = record_schema(
    [
        (name, FLOAT)
        for name in (
            "time_s",
            "altitude_km",
            "latitude_deg",
            "longitude_deg",
            "speed_mps",
            "fpa_deg",
            "heading_deg",
            "alpha_deg",
            "bank_deg",
            "mach",
            "heat_rate_kw_m2",
            "load_g",
            "dynamic_pressure_kpa",
            "range_to_go_km",
        )
    ],
)
"""The columns of :attr:`ReentryResult.trajectory`."""
