"""The rendezvous stage's typed input and result (one Parquet row plus a trajectory table)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import pandas as pd

from ovtraj.astro.constants import EarthModel
from ovtraj.astro.epoch import Epoch
from ovtraj.astro.propagation import PropagationResult
from ovtraj.config.scenario import RendezvousSettings
from ovtraj.store.records import BOOL, FLOAT, INT, TEXT, Column, RowColumns, record_schema

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
        """Flat, JSON- and Parquet-friendly record of :data:`ROW`; SI units named in the
        keys."""
        return ROW.row(self)


_RSW = ("radial", "along_track", "cross_track")
_STATE = ("x_m", "y_m", "z_m", "vx_mps", "vy_mps", "vz_mps")


def _burn(which: str) -> Callable[[RendezvousResult], Impulse | None]:
    return lambda r: getattr(r, which)


def _burn_columns(which: str) -> list[Column]:
    """The time and epoch of the impulse ``which`` (``burn1``: the first)."""
    burn = _burn(which)
    return [
        Column(
            f"{which}_t_s",
            FLOAT,
            "s from epoch_utc: the impulse",
            lambda r: burn(r).t_s if burn(r) else None,
        ),
        Column(
            f"{which}_epoch_utc",
            TEXT,
            "ISO UTC of the impulse",
            lambda r: r.epoch.plus_seconds(burn(r).t_s).iso() if burn(r) else None,
        ),
    ]


def _impulse_columns(name: str, which: str) -> list[Column]:
    """The components [m/s] of the impulse ``which``: ECI x, y, z, then radial,
    along-track, cross-track."""
    burn = _burn(which)

    def eci(k: int) -> Callable[[RendezvousResult], float | None]:
        return lambda r: float(burn(r).eci_mps[k]) if burn(r) else None

    def rsw(k: int) -> Callable[[RendezvousResult], float | None]:
        return lambda r: float(burn(r).rsw_mps[k]) if burn(r) else None

    return [
        *[
            Column(f"{name}_eci_{axis}_mps", FLOAT, f"m/s: ECI {axis}", eci(k))
            for k, axis in enumerate("xyz")
        ],
        *[
            Column(f"{name}_{axis}_mps", FLOAT, f"m/s: {axis.replace('_', '-')} (RSW)", rsw(k))
            for k, axis in enumerate(_RSW)
        ],
    ]


ROW = RowColumns(
    [
        Column(
            "kind",
            TEXT,
            "rendezvous (with the target) or transfer (to a circular orbit)",
            lambda r: r.kind,
        ),
        Column("feasible", BOOL, "the stage met every limit", lambda r: r.feasible),
        Column("reason", TEXT, "why it is infeasible (empty when feasible)", lambda r: r.reason),
        Column(
            "epoch_utc", TEXT, "ISO UTC: the epoch the times count from", lambda r: r.epoch.iso()
        ),
        Column("t0_s", FLOAT, "s from epoch_utc: the stage's start", lambda r: r.t0_s),
        Column("wait_time_s", FLOAT, "s: the start to the first impulse", lambda r: r.wait_time_s),
        Column(
            "phasing_wait_s",
            FLOAT,
            "s: the phasing wait checked against max_wait_time_s (before the J2 correction "
            "moves the first impulse)",
            lambda r: r.phasing_wait_s,
        ),
        Column(
            "transfer_time_s",
            FLOAT,
            "s: the first impulse to the second",
            lambda r: r.transfer_time_s,
        ),
        Column(
            "transfer_time_two_body_s",
            FLOAT,
            "s: the two-body Hohmann transfer's",
            lambda r: r.transfer_time_two_body_s,
        ),
        Column("dv1_mps", FLOAT, "m/s: the first impulse", lambda r: _magnitude(r.burn1)),
        Column("dv2_mps", FLOAT, "m/s: the second impulse", lambda r: _magnitude(r.burn2)),
        Column("dv_total_mps", FLOAT, "m/s: both impulses", lambda r: r.dv_total_mps),
        Column(
            "dv1_two_body_mps",
            FLOAT,
            "m/s: the Hohmann transfer's first",
            lambda r: r.dv1_two_body_mps,
        ),
        Column(
            "dv2_two_body_mps",
            FLOAT,
            "m/s: the Hohmann transfer's second",
            lambda r: r.dv2_two_body_mps,
        ),
        Column(
            "lead_angle_deg",
            FLOAT,
            "deg: the target's phase ahead of the chaser at the first impulse",
            lambda r: _deg(r.lead_angle_rad),
        ),
        Column(
            "lead_angle_two_body_deg",
            FLOAT,
            "deg: the two-body lead angle of the Hohmann transfer",
            lambda r: _deg(r.lead_angle_two_body_rad),
        ),
        Column(
            "plane_difference_deg",
            FLOAT,
            "deg: between the chaser's and the target's orbit planes",
            lambda r: _deg(r.plane_difference_rad),
        ),
        Column(
            "miss_distance_m",
            FLOAT,
            "m: at arrival, after the J2 correction",
            lambda r: r.miss_distance_m,
        ),
        Column(
            "initial_miss_distance_m",
            FLOAT,
            "m: at arrival, before the J2 correction",
            lambda r: r.initial_miss_distance_m,
        ),
        Column("iterations", INT, "the J2 correction's iterations", lambda r: r.iterations),
        Column(
            "evaluations", INT, "the J2 correction's transfer evaluations", lambda r: r.evaluations
        ),
        Column("solver_message", TEXT, "the J2 correction's last word", lambda r: r.solver_message),
        *_burn_columns("burn1"),
        *_burn_columns("burn2"),
        *_impulse_columns("dv1", "burn1"),
        *_impulse_columns("dv2", "burn2"),
    ],
    required=("kind", "feasible"),
)
"""The rendezvous and transfer stages' row (:meth:`RendezvousResult.to_row`)."""

ROW_SCHEMA = ROW.schema
"""The columns of :meth:`RendezvousResult.to_row`, as stored."""

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
