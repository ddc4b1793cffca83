"""The result of one deorbit-burn solve: summary figures, the iteration history, a table row.

Units are in the field names (deg, km, m/s, s); errors are actual minus target at the entry
radius; the along-track error is the u error times r_E. Prediction errors are the on-board
prediction at the cut-off minus the propagated entry (what the seed calls the prediction
error: the only source of the fpa error under strategy 2).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import pandas as pd

from ovtraj.store.records import plain
from ovtraj.studies.deorbit_burn.iteration import IterationRecord

__all__ = ["DeorbitBurnResult"]


@dataclass(frozen=True)
class DeorbitBurnResult:
    """One solve of a deorbit-burn problem (see the module notes for units and signs)."""

    name: str
    strategy: int
    converged: bool
    reason: str | None  # why the result is not usable, None when converged
    single_burn_feasible: bool  # the waiting and transfer orbits meet (seed eq. 4/6)
    iterations: int  # trajectories flown by the eq. 27 iteration, the converged one included
    u_open_deg: float
    burn_duration_s: float
    dv_mps: float
    burn_angle_deg: float  # from -along-track (-v at ignition), positive away from the Earth
    entry_u_deg: float
    entry_fpa_deg: float
    entry_speed_mps: float
    entry_u_error_deg: float
    entry_fpa_error_deg: float
    entry_speed_error_mps: float
    along_track_error_km: float
    prediction_u_error_deg: float
    prediction_fpa_error_deg: float
    prediction_speed_error_mps: float
    impulsive_u_deg: float  # seed eq. 6 burn point (eq. 10 angle) or the angle's two-body point
    impulsive_dv_mps: float  # seed eq. 9
    impulsive_burn_angle_deg: float  # seed eq. 10
    transfer_a_km: float  # seed sec. 1, osculating at the entry
    transfer_e: float
    transfer_argp_deg: float
    transfer_apoapsis_altitude_km: float
    transfer_mean_apoapsis_altitude_km: float  # what the single-burn condition uses
    waiting_altitude_km: float  # mean a - R_E
    solve_time_s: float
    history: tuple[IterationRecord, ...] = field(default_factory=tuple)

    def to_row(self) -> dict[str, Any]:
        """Flat scalars for a table, the run store or ``--json`` (NaN becomes None)."""
        row = {key: getattr(self, key) for key in self.__dataclass_fields__ if key != "history"}
        return plain(row)

    def history_frame(self) -> pd.DataFrame:
        """One row per iteration: u_open, dv, burn duration, entry errors."""
        return pd.DataFrame([record.as_dict() for record in self.history])
