"""The rendezvous stage's typed input and result (one Parquet row plus a trajectory table)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import pandas as pd

from ovtraj.astro.constants import EarthModel
from ovtraj.astro.epoch import Epoch
from ovtraj.astro.propagation import PropagationResult
from ovtraj.config.scenario import RendezvousSettings
from ovtraj.store.records import BOOL, FLOAT, INT, TEXT, plain, record_schema

TransferKind = Literal["rendezvous", "transfer"]


@dataclass(frozen=True)
class RendezvousInput:
    """A chaser and a target at ``t0_s`` (s from ``epoch``), Cartesian ECI (m, m/s).

    ``target_coast``: optionally, the target's dense trajectory on this input's time
    axis (e.g. one ephemeris shared by every design of a mission DoE); the stage uses it
    where it covers ``t0_s`` onwards and propagates ``target_state`` where it does not.
    """

    epoch: Epoch
    t0_s: float
    chaser_state: np.ndarray
    target_state: np.ndarray
    settings: RendezvousSettings
    miss_tolerance_m: float
    max_impulse_mps: float
    integrator_tol: float
    earth: EarthModel
    target_coast: PropagationResult | None = None


@dataclass(frozen=True)
class TransferInput:
    """A chaser to be moved to a circular orbit of ``target_altitude_m`` (no target).

    The transfer starts at ``burn_time_s`` (s from ``epoch``; defaults to ``t0_s``).
    """

    epoch: Epoch
    t0_s: float
    chaser_state: np.ndarray
    target_altitude_m: float
    settings: RendezvousSettings
    miss_tolerance_m: float
    max_impulse_mps: float
    integrator_tol: float
    earth: EarthModel
    burn_time_s: float | None = None


@dataclass(frozen=True)
class Impulse:
    """An impulsive manoeuvre: time (s from the epoch), ECI and local RSW components (m/s)."""

    t_s: float
    eci_mps: np.ndarray
    rsw_mps: np.ndarray  # radial, along-track, cross-track

    @property
    def magnitude_mps(self) -> float:
        return float(np.linalg.norm(self.eci_mps))


@dataclass(frozen=True)
class RendezvousResult:
    """Outcome of the rendezvous (or target-less transfer) stage.

    Infeasible results keep every field the stage reached; the rest are ``None``
    (never NaN), and ``reason`` says why.

    ``phasing_wait_s`` is the wait the stage checks against ``max_wait_time_s``: the
    phasing wait refined on the propagated phase, before the J2 correction moves the first
    burn (``wait_time_s``, up to ``burn_epoch_window_s`` away). A rendezvous refused for its
    wait keeps it too: refined when it exceeds the limit by less than the burn window, the
    secular estimate beyond (on the default scenario 150-340 s from the refined wait at
    the waits the limit allows, 448 s at a 3.4-day wait).
    """

    kind: TransferKind
    feasible: bool
    reason: str
    epoch: Epoch
    t0_s: float
    wait_time_s: float | None = None
    phasing_wait_s: float | None = None
    burn1: Impulse | None = None
    burn2: Impulse | None = None
    transfer_time_s: float | None = None
    transfer_time_two_body_s: float | None = None
    dv1_two_body_mps: float | None = None
    dv2_two_body_mps: float | None = None
    lead_angle_rad: float | None = None
    lead_angle_two_body_rad: float | None = None
    plane_difference_rad: float | None = None
    miss_distance_m: float | None = None
    initial_miss_distance_m: float | None = None
    iterations: int | None = None
    evaluations: int | None = None
    solver_message: str = ""
    final_state: np.ndarray | None = None  # chaser after the second impulse
    trajectory: pd.DataFrame = field(default_factory=pd.DataFrame)

    @property
    def dv_total_mps(self) -> float | None:
        if self.burn1 is None or self.burn2 is None:
            return None
        return self.burn1.magnitude_mps + self.burn2.magnitude_mps

    @property
    def arrival_time_s(self) -> float | None:
        return self.burn2.t_s if self.burn2 is not None else None

    def to_row(self) -> dict[str, Any]:
        """Flat, JSON- and Parquet-friendly record; SI units named in the keys."""
        row: dict[str, Any] = {
            "kind": self.kind,
            "feasible": self.feasible,
            "reason": self.reason,
            "epoch_utc": self.epoch.iso(),
            "t0_s": self.t0_s,
            "wait_time_s": self.wait_time_s,
            "phasing_wait_s": self.phasing_wait_s,
            "transfer_time_s": self.transfer_time_s,
            "transfer_time_two_body_s": self.transfer_time_two_body_s,
            "dv1_mps": _magnitude(self.burn1),
            "dv2_mps": _magnitude(self.burn2),
            "dv_total_mps": self.dv_total_mps,
            "dv1_two_body_mps": self.dv1_two_body_mps,
            "dv2_two_body_mps": self.dv2_two_body_mps,
            "lead_angle_deg": _deg(self.lead_angle_rad),
            "lead_angle_two_body_deg": _deg(self.lead_angle_two_body_rad),
            "plane_difference_deg": _deg(self.plane_difference_rad),
            "miss_distance_m": self.miss_distance_m,
            "initial_miss_distance_m": self.initial_miss_distance_m,
            "iterations": self.iterations,
            "evaluations": self.evaluations,
            "solver_message": self.solver_message,
        }
        for name, burn in (("burn1", self.burn1), ("burn2", self.burn2)):
            row[f"{name}_t_s"] = burn.t_s if burn else None
            row[f"{name}_epoch_utc"] = self.epoch.plus_seconds(burn.t_s).iso() if burn else None
        for name, burn in (("dv1", self.burn1), ("dv2", self.burn2)):
            for axis, k in zip("xyz", range(3), strict=True):
                row[f"{name}_eci_{axis}_mps"] = float(burn.eci_mps[k]) if burn else None
            for axis, k in zip(("radial", "along_track", "cross_track"), range(3), strict=True):
                row[f"{name}_{axis}_mps"] = float(burn.rsw_mps[k]) if burn else None
        return {k: plain(v) for k, v in row.items()}


_RSW = ("radial", "along_track", "cross_track")
_STATE = ("x_m", "y_m", "z_m", "vx_mps", "vy_mps", "vz_mps")

ROW_SCHEMA = record_schema(
    [
        ("kind", TEXT),
        ("feasible", BOOL),
        ("reason", TEXT),
        ("epoch_utc", TEXT),
        ("t0_s", FLOAT),
        ("wait_time_s", FLOAT),
        ("phasing_wait_s", FLOAT),
        ("transfer_time_s", FLOAT),
        ("transfer_time_two_body_s", FLOAT),
        ("dv1_mps", FLOAT),
        ("dv2_mps", FLOAT),
        ("dv_total_mps", FLOAT),
        ("dv1_two_body_mps", FLOAT),
        ("dv2_two_body_mps", FLOAT),
        ("lead_angle_deg", FLOAT),
        ("lead_angle_two_body_deg", FLOAT),
        ("plane_difference_deg", FLOAT),
        ("miss_distance_m", FLOAT),
        ("initial_miss_distance_m", FLOAT),
        ("iterations", INT),
        ("evaluations", INT),
        ("solver_message", TEXT),
        *[
            (f"{burn}_{what}", kind)
            for burn in ("burn1", "burn2")
            for what, kind in (("t_s", FLOAT), ("epoch_utc", TEXT))
        ],
        *[
            (f"{dv}_{axis}_mps", FLOAT)
            for dv in ("dv1", "dv2")
            for axis in ("eci_x", "eci_y", "eci_z", *_RSW)
        ],
    ],
    required=("kind", "feasible"),
)
"""The columns of :meth:`RendezvousResult.to_row` (the rendezvous and transfer stages)."""

TRAJECTORY_SCHEMA = record_schema(
    [
        ("t_s", FLOAT),
        ("phase", TEXT),
        *[(f"chaser_{axis}", FLOAT) for axis in _STATE],
        *[(f"target_{axis}", FLOAT) for axis in _STATE],
        ("chaser_altitude_m", FLOAT),
        ("range_m", FLOAT),
    ],
)
"""The columns of :attr:`RendezvousResult.trajectory` (target columns null without a target)."""


def _magnitude(burn: Impulse | None) -> float | None:
    return burn.magnitude_mps if burn is not None else None


def _deg(angle: float | None) -> float | None:
    return math.degrees(angle) if angle is not None else None
