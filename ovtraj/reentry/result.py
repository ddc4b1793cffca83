"""The reentry stage's result: a flat row for the run store and a trajectory table."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import pandas as pd

from ovtraj.astro.epoch import Epoch
from ovtraj.store.records import BOOL, FLOAT, INT, TEXT, plain, record_schema


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
        row: dict[str, Any] = {
            "feasible": self.feasible,
            "reason": self.reason,
            "flags": ";".join(self.flags),
            "entry_epoch_utc": self.epoch.iso(),
            "miss_distance_km": _scaled(self.miss_distance_m, 1e-3),
            "flight_time_s": self.flight_time_s,
            "terminal_epoch_utc": None
            if self.flight_time_s is None
            else self.epoch.plus_seconds(self.flight_time_s).iso(),
            "terminal_altitude_km": _scaled(self.terminal_altitude_m, 1e-3),
            "terminal_speed_mps": self.terminal_speed_mps,
            "terminal_lat_deg": _deg(self.terminal_latitude_rad),
            "terminal_lon_deg": _deg(self.terminal_longitude_rad),
            "terminal_fpa_deg": _deg(self.terminal_fpa_rad),
            "terminal_heading_deg": _deg(self.terminal_heading_rad),
            "max_heat_rate_kw_m2": _scaled(self.max_heat_rate_w_m2, 1e-3),
            "max_heat_rate_time_s": self.max_heat_rate_time_s,
            "max_load_g": self.max_load_g,
            "max_load_time_s": self.max_load_time_s,
            "max_dynamic_pressure_kpa": _scaled(self.max_dynamic_pressure_pa, 1e-3),
            "max_dynamic_pressure_time_s": self.max_dynamic_pressure_time_s,
            "max_bank_deg": _deg(self.max_bank_rad),
            "heat_rate_margin": self.heat_rate_margin,
            "load_margin": self.load_margin,
            "dynamic_pressure_margin": self.dynamic_pressure_margin,
            "bank_margin": self.bank_margin,
            "sigma0_deg": _deg(self.sigma0_rad),
            "sigma1_deg": _deg(self.sigma1_rad),
            "reversals": self.reversals,
            "newton_iterations": self.newton_iterations,
            "golden_evaluations": self.golden_evaluations,
            "trajectories": self.trajectories,
            "wall_time_s": self.wall_time_s,
        }
        return {k: plain(v) for k, v in row.items()}


ROW_SCHEMA = record_schema(
    [
        ("feasible", BOOL),
        ("reason", TEXT),
        ("flags", TEXT),
        ("entry_epoch_utc", TEXT),
        ("miss_distance_km", FLOAT),
        ("flight_time_s", FLOAT),
        ("terminal_epoch_utc", TEXT),
        *[
            (f"terminal_{name}", FLOAT)
            for name in (
                "altitude_km",
                "speed_mps",
                "lat_deg",
                "lon_deg",
                "fpa_deg",
                "heading_deg",
            )
        ],
        ("max_heat_rate_kw_m2", FLOAT),
        ("max_heat_rate_time_s", FLOAT),
        ("max_load_g", FLOAT),
        ("max_load_time_s", FLOAT),
        ("max_dynamic_pressure_kpa", FLOAT),
        ("max_dynamic_pressure_time_s", FLOAT),
        ("max_bank_deg", FLOAT),
        *[(f"{name}_margin", FLOAT) for name in ("heat_rate", "load", "dynamic_pressure", "bank")],
        ("sigma0_deg", FLOAT),
        ("sigma1_deg", FLOAT),
        ("reversals", INT),
        ("newton_iterations", INT),
        ("golden_evaluations", INT),
        ("trajectories", INT),
        ("wall_time_s", FLOAT),
    ],
    required=("feasible",),
)
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
