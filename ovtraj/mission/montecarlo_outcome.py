"""What one dispersed run of a plan's Monte Carlo records (:mod:`ovtraj.mission.montecarlo`).

A run ends with its landing point (geocentric latitude and longitude at the terminal
interface, on the spherical Earth the miss is measured on) and miss, whether it reached the
terminal speed, and the path maxima. Nothing raises out of a run: a stage that fails
(:class:`StageFailed`) ends it with the stage and the reason.

Every run also records the dV it spent (:data:`MANOEUVRES`): the magnitude of each
impulse as executed, after its errors (the deorbit burn as cut off on line), under the
plan's name of the manoeuvre; the closed loop's mid-course corrections, which the plan
does not hold, as ``rendezvous corrections`` (their sum; the open loop flies none: 0). A
manoeuvre the run did not reach has no value, nor has the total.

Stored, a run is a row of :data:`RUN_SCHEMA` per loop (:func:`outcome_row`), read back by
:func:`outcomes_of`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
from numpy.typing import NDArray

from ovtraj.store.records import BOOL, FLOAT, INT, TEXT, record_schema

__all__ = [
    "CORRECTIONS",
    "IMPULSES",
    "MANOEUVRES",
    "PATH_LIMITS",
    "RUN_SCHEMA",
    "STORED_RUN_SCHEMA",
    "RunOutcome",
    "StageFailed",
    "outcome_row",
    "outcomes_of",
]

PATH_LIMITS = ("max_heat_rate_w_m2", "max_load_g", "max_dynamic_pressure_pa")
# Every manoeuvre whose dV a run records, in time order, and its stored column: the plan's
# impulses under the plan's names, and the closed loop's mid-course corrections (not planned).
CORRECTIONS = "rendezvous corrections"
MANOEUVRES = {
    "rendezvous burn 1": "dv_rendezvous_1_mps",
    CORRECTIONS: "dv_rendezvous_corrections_mps",
    "rendezvous burn 2": "dv_rendezvous_2_mps",
    "transfer burn 1": "dv_transfer_1_mps",
    "transfer burn 2": "dv_transfer_2_mps",
    "deorbit burn": "dv_deorbit_mps",
}
# The plan's impulses in the order of MissionPlan.impulses() (the index of Perturbation.burn).
IMPULSES = tuple(name for name in MANOEUVRES if name != CORRECTIONS)

RUN_SCHEMA = record_schema(
    [
        ("run", INT),
        ("loop", TEXT),
        ("landed", BOOL),
        ("failed_stage", TEXT),
        ("reason", TEXT),
        ("landing_miss_m", FLOAT),
        ("landing_latitude_deg", FLOAT),
        ("landing_longitude_deg", FLOAT),
        ("arrival_miss_m", FLOAT),
        *[(column, FLOAT) for column in MANOEUVRES.values()],
        ("dv_total_mps", FLOAT),
        *[(name, FLOAT) for name in PATH_LIMITS],
        ("wall_time_s", FLOAT),
    ],
    required=("run", "loop", "landed"),
)
"""One flown run of one loop (``closed``/``open``); ``wall_time_s`` is timing only. The
``dv_*_mps`` columns: the dV each manoeuvre spent (:data:`MANOEUVRES`) and their sum, null
for a manoeuvre the run did not reach (and then for the total)."""
STORED_RUN_SCHEMA = pa.schema([f for f in RUN_SCHEMA if f.name != "wall_time_s"])
"""The stored rows (the wall times go to the batch markers)."""


@dataclass
class RunOutcome:
    """One run flown: reached the terminal speed or not, where (the miss from the landing
    site and the point itself), and the path maxima.

    ``dv_mps``: the dV [m/s] each manoeuvre the run executed spent (keys of
    :data:`MANOEUVRES`); ``dv_total_mps``: their sum once it executed all of them."""

    run: int
    loop: str  # "closed" or "open"
    landed: bool
    failed_stage: str | None = None
    reason: str | None = None
    landing_miss_m: float | None = None
    maxima: dict[str, float] = field(default_factory=dict)
    arrival_miss_m: float | None = None
    dv_total_mps: float | None = None
    dv_mps: dict[str, float] = field(default_factory=dict)
    # Where the run reached the terminal interface [deg] (geocentric: the miss's sphere).
    landing_latitude_deg: float | None = None
    landing_longitude_deg: float | None = None

    def spend(self, manoeuvre: str, *executed: NDArray[np.float64]) -> None:
        """Record ``manoeuvre`` as flown: the sum of its executed impulses' magnitudes
        [m/s] (none: 0); the total once every manoeuvre is recorded."""
        self.dv_mps[manoeuvre] = float(sum(np.linalg.norm(dv) for dv in executed))
        if set(MANOEUVRES) <= set(self.dv_mps):
            self.dv_total_mps = sum(self.dv_mps[name] for name in MANOEUVRES)


class StageFailed(Exception):
    """A stage of a closed-loop flight failed: the run ends with ``stage`` and ``reason``."""

    def __init__(self, stage: str, reason: str) -> None:
        super().__init__(reason)
        self.stage, self.reason = stage, reason


def outcome_row(outcome: RunOutcome, wall_time_s: float) -> dict[str, Any]:
    """The row of :data:`RUN_SCHEMA` of one loop of one run; ``wall_time_s`` [s] its flight's."""
    return {
        "run": outcome.run,
        "loop": outcome.loop,
        "landed": outcome.landed,
        "failed_stage": outcome.failed_stage,
        "reason": outcome.reason,
        "landing_miss_m": outcome.landing_miss_m,
        "landing_latitude_deg": outcome.landing_latitude_deg,
        "landing_longitude_deg": outcome.landing_longitude_deg,
        "arrival_miss_m": outcome.arrival_miss_m,
        **{c: outcome.dv_mps.get(name) for name, c in MANOEUVRES.items()},
        "dv_total_mps": outcome.dv_total_mps,
        **{name: outcome.maxima.get(name) for name in PATH_LIMITS},
        "wall_time_s": wall_time_s,
    }


def outcomes_of(frame: pd.DataFrame, loop: str) -> list[RunOutcome]:
    """The stored rows of one loop as outcomes (for :func:`summarise`)."""

    def value(row: Any, name: str) -> Any:
        item = row[name]
        return None if item is None or (isinstance(item, float) and math.isnan(item)) else item

    outcomes = []
    for _, row in frame[frame["loop"] == loop].iterrows():
        outcomes.append(
            RunOutcome(
                run=int(row["run"]),
                loop=loop,
                landed=bool(row["landed"]),
                failed_stage=value(row, "failed_stage"),
                reason=value(row, "reason"),
                landing_miss_m=value(row, "landing_miss_m"),
                landing_latitude_deg=value(row, "landing_latitude_deg"),
                landing_longitude_deg=value(row, "landing_longitude_deg"),
                maxima={n: float(row[n]) for n in PATH_LIMITS if value(row, n) is not None},
                arrival_miss_m=value(row, "arrival_miss_m"),
                dv_total_mps=value(row, "dv_total_mps"),
                dv_mps={
                    name: float(row[column])
                    for name, column in MANOEUVRES.items()
                    if value(row, column) is not None
                },
            )
        )
    return outcomes
