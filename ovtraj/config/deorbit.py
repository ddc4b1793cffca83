"""Settings of the deorbit stage (patent step 103).

Angles in degrees and distances in km in the file (the key names say so); the
stage converts to SI once, in :mod:`ovtraj.deorbit.inputs`.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field, field_validator, model_serializer, model_validator

from ovtraj.astro.epoch import Epoch
from ovtraj.config.base import StrictModel, bounded


class PreparationOrbitConfig(StrictModel):
    """Stand-alone start: the OV on a near-circular preparation orbit (altitude H_dp).

    The mission chain passes the OV's actual state instead. ``mean`` elements
    (first-order J2, zero mean eccentricity) define a circular orbit under J2.
    """

    epoch_utc: str
    element_set: Literal["mean", "osculating"] = "mean"
    altitude_km: float = bounded(unit="km", gt=120, le=2000)
    inclination_deg: float = bounded(unit="deg", ge=0, le=180)
    raan_deg: float = bounded(unit="deg", ge=-360, le=360)
    arg_latitude_deg: float = bounded(unit="deg", ge=-360, le=360)

    @field_validator("epoch_utc")
    @classmethod
    def _parses_as_utc(cls, value: str) -> str:
        Epoch.from_iso(value)
        return value


class EntryRegionConfig(StrictModel):
    """Where and how the OV must reach the entry interface.

    The region is a latitude/longitude box around the entry point (geocentric,
    spherical Earth); the flight-path angle is inertial, at the entry altitude.
    """

    latitude_deg: float = bounded(unit="deg", ge=-90, le=90)
    longitude_deg: float = bounded(unit="deg", ge=-180, le=360)
    latitude_tolerance_deg: float = bounded(unit="deg", gt=0, le=20)
    longitude_tolerance_deg: float = bounded(unit="deg", gt=0, le=45)
    altitude_km: float = bounded(unit="km", ge=60, le=300)
    fpa_min_deg: float = bounded(unit="deg", gt=-30, lt=0, description="steepest allowed")
    fpa_max_deg: float = bounded(unit="deg", gt=-30, lt=0, description="shallowest allowed")
    fpa_target_deg: float = bounded(
        unit="deg", gt=-30, lt=0, description="aim of the two-body estimate"
    )
    pass_direction: Literal["northbound", "southbound", "any"] = Field(
        description="which passes may be used: the approach to the landing site sets it"
    )

    @model_validator(mode="after")
    def _ordered_angles(self) -> EntryRegionConfig:
        if not self.fpa_min_deg <= self.fpa_target_deg <= self.fpa_max_deg:
            raise ValueError(
                f"needs fpa_min_deg <= fpa_target_deg <= fpa_max_deg, got {self.fpa_min_deg:g}, "
                f"{self.fpa_target_deg:g}, {self.fpa_max_deg:g}"
            )
        return self


class DeorbitSolverConfig(StrictModel):
    """SLSQP correction under J2 and the finite-difference steps of its gradients."""

    max_iterations: int = bounded(ge=1, le=10000, description="SLSQP iterations per pass")
    time_limit_s: float = bounded(
        unit="s", gt=0, le=86400, description="wall time of the stage: forecast and every pass"
    )
    ftol: float = bounded(gt=0, lt=1, description="SLSQP ftol on the scaled objective")
    time_scale_s: float = bounded(unit="s", gt=0, le=86400, description="burn-epoch variable unit")
    dv_scale_mps: float = bounded(unit="m/s", gt=0, le=10000, description="impulse variable unit")
    burn_window_s: float = bounded(
        unit="s", gt=0, le=86400, description="the correction may move the burn by up to this"
    )
    finite_difference_step: float = bounded(gt=0, lt=0.1, description="scaled variables")
    # SLSQP boxes each RSW component of the impulse at this multiple of the impulse limit.
    # At least 1, so the box holds every impulse the |dv| <= limit constraint allows and
    # never decides a solution; above estimate_margin, so the two-body start (refused
    # beyond the limit times estimate_margin) is never clipped; and finite, so SLSQP's
    # intermediate iterates, which may break the |dv| constraint, stay burns the descent
    # model can fly. No bound binds on the chain's 22 reference designs: 1, 1.05, 3 and 10
    # give the same results bit for bit (measured). The default is the bound every
    # scenario was solved with before it became a setting; at that value the setting is
    # left out of the resolved scenario.
    impulse_bound_factor: float = bounded(
        ge=1,
        le=10,
        default=1.5,
        description="each impulse component is bounded by the impulse limit times this",
    )
    constraint_tolerance: float = bounded(
        gt=0, lt=1, description="accepted violation, as a fraction of each constraint's scale"
    )
    max_passes: int = bounded(ge=1, le=1000, description="passes tried before giving up")
    estimate_margin: float = bounded(
        ge=1,
        le=2,
        description="refuse without a solve when the two-body impulse at the shallowest "
        "angle exceeds the limit times this",
    )
    nearest_point_tolerance_s: float = bounded(
        unit="s", gt=0, le=10, description="time accuracy of the virtual entry point"
    )
    pass_cost_margin_mps: float | None = bounded(
        default=None,
        unit="m/s",
        gt=0,
        le=1000,
        description="a pass is taken when its corrected impulse exceeds the two-body tangential "
        "impulse at the shallowest allowed entry angle by at most this; a dearer pass (its burn "
        "pinned at the preparation orbit's start and steered radially) is passed over for the "
        "next; null: the first pass whose constraints are met, whatever it costs",
    )

    @model_serializer(mode="wrap")
    def _bound_factor_when_changed(self, handler: Any) -> dict[str, Any]:
        """``impulse_bound_factor`` left out at its default: the resolved scenario, its run
        ids and the stored reference front's key are those from before the setting."""
        data = handler(self)
        default = type(self).model_fields["impulse_bound_factor"].default
        if data.get("impulse_bound_factor") == default:
            data.pop("impulse_bound_factor", None)
        return data


class DeorbitSettings(StrictModel):
    preparation_orbit: PreparationOrbitConfig
    entry: EntryRegionConfig
    horizon_h: float = bounded(unit="h", gt=0, le=720, description="ground-track forecast span")
    max_descent_revolutions: float = bounded(
        gt=0, le=3, description="burn-to-entry time limit, in preparation-orbit periods"
    )
    solver: DeorbitSolverConfig
    trajectory_step_s: float = bounded(
        unit="s", ge=0.01, le=3600, description="trajectory table sampling"
    )
