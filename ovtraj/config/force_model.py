"""Settings of the high-fidelity force model (``configs/force_model.yaml``).

Validation only: the terms the orbit is flown under, their data sources and constants.
One section per term of :data:`ovtraj.astro.forces.terms.FORCE_TERMS`, named after it;
a switchable term's section carries ``enabled``.
The spacecraft's own figures (areas, coefficients, mass) are the scenario's
``vehicle.body`` and ``target.body`` (:class:`ovtraj.config.scenario.BodyConfig`).
"""

from __future__ import annotations

from functools import lru_cache
from typing import Literal

from pydantic import Field, field_validator, model_validator

from ovtraj.astro.forces.terms import SWITCHABLE, check_term_names
from ovtraj.config.base import StrictModel, bounded, load_model

# heyoka 7.13 ships EGM2008 to degree and order 150 (``heyoka.model.egm2008_acc``).
EGM2008_MAX_DEGREE = 150


class GravitySettings(StrictModel):
    """The Earth's field: EGM2008 to ``degree`` x ``order``, or the chain's J2."""

    model: Literal["egm2008", "j2"]
    degree: int = bounded(ge=2, le=EGM2008_MAX_DEGREE, description="EGM2008 maximum degree")
    order: int = bounded(ge=0, le=EGM2008_MAX_DEGREE, description="EGM2008 maximum order")

    @model_validator(mode="after")
    def _order_not_above_degree(self) -> GravitySettings:
        if self.order > self.degree:
            raise ValueError(f"order ({self.order}) must not exceed degree ({self.degree})")
        return self


class DragSettings(StrictModel):
    enabled: bool
    model: Literal["nrlmsise00", "jb08"]


class Jb08Indices(StrictModel):
    """JB2008's solar indices beyond F10.7 [sfu] and the storm rate [nT/h], held constant."""

    s107_sfu: float = bounded(unit="sfu", ge=0, le=500)
    s107a_sfu: float = bounded(unit="sfu", ge=0, le=500)
    m107_sfu: float = bounded(unit="sfu", ge=0, le=500)
    m107a_sfu: float = bounded(unit="sfu", ge=0, le=500)
    y107_sfu: float = bounded(unit="sfu", ge=0, le=500)
    y107a_sfu: float = bounded(unit="sfu", ge=0, le=500)
    ddst_dt_nt_h: float = bounded(unit="nT/h", ge=-1000, le=1000)


class SpaceWeatherSettings(StrictModel):
    """``bundled``: heyoka's CelesTrak table at each instant; ``constant``: the values here."""

    source: Literal["bundled", "constant"]
    f107_sfu: float = bounded(unit="sfu", ge=0, le=500, description="F10.7 (constant source)")
    f107a_sfu: float = bounded(unit="sfu", ge=0, le=500, description="81-day mean F10.7")
    ap: float = bounded(ge=0, le=400, description="daily Ap (constant source)")
    jb08: Jb08Indices


class EarthOrientationSettings(StrictModel):
    max_extrapolation_days: float = bounded(
        unit="day", ge=0, le=365, description="the last EOP held beyond the bundled data"
    )


class SunSettings(StrictModel):
    enabled: bool
    mu_m3_s2: float = bounded(unit="m^3/s^2", gt=0, le=1e21)
    vsop2013_threshold: float = bounded(ge=0, le=1e-3, description="VSOP2013 truncation")


class MoonSettings(StrictModel):
    enabled: bool
    mu_m3_s2: float = bounded(unit="m^3/s^2", gt=0, le=1e14)
    elp2000_threshold: float = bounded(ge=0, le=1e-2, description="ELP2000 truncation")


class RadiationPressureSettings(StrictModel):
    enabled: bool
    pressure_n_m2: float = bounded(unit="N/m^2", gt=0, le=1e-4)
    astronomical_unit_m: float = bounded(unit="m", gt=1e11, le=2e11)
    sun_radius_m: float = bounded(unit="m", gt=1e8, le=1e9)
    shadow_sharpness: float = bounded(gt=0, le=100, description="tanh slope in the penumbra")
    shadow_step_edge: float = bounded(
        gt=0, le=20, description="the shadow argument at which a Taylor step ends"
    )


class EllipsoidSettings(StrictModel):
    equatorial_radius_m: float = bounded(unit="m", gt=6.0e6, le=7.0e6)
    eccentricity_squared: float = bounded(ge=0, lt=0.1)


class ClosedLoopSettings(StrictModel):
    phasing_retarget_interval_h: float = bounded(
        unit="h", gt=0, le=240, description="the rendezvous re-solved this often while phasing"
    )


class TargetFitSettings(StrictModel):
    sgp4_reference_density: float = bounded(
        unit="kg/m^2/ER", gt=0, le=10, description="SGP4's rho_0 in B* = C_D A rho_0 / (2 m)"
    )
    fit_ballistic: bool
    max_evaluations: int = bounded(ge=1, le=1000, description="least-squares evaluations")
    time_limit_s: float = bounded(unit="s", gt=0, le=7200, description="one fit's wall time")
    log_ballistic_step: float = bounded(gt=0, le=0.1, description="difference step")
    ballistic_bounds: tuple[float, float] = Field(
        description="C_D A / m kept within these factors of its start (lower < 1 < upper)"
    )

    @field_validator("ballistic_bounds")
    @classmethod
    def _around_one(cls, bounds: tuple[float, float]) -> tuple[float, float]:
        if not 0.0 < bounds[0] < 1.0 < bounds[1] <= 1.0e4:
            raise ValueError("need 0 < lower < 1 < upper <= 1e4 (factors of the start)")
        return bounds


class IntegrationSettings(StrictModel):
    tolerance: float = bounded(gt=0, lt=1e-3, description="heyoka Taylor tolerance")
    max_arc_days: float = bounded(unit="day", gt=0, le=365, description="longest arc flown")


class ForceModelSettings(StrictModel):
    """``configs/force_model.yaml``: each term of the high-fidelity orbit and its data."""

    gravity: GravitySettings
    drag: DragSettings
    space_weather: SpaceWeatherSettings
    earth_orientation: EarthOrientationSettings
    sun: SunSettings
    moon: MoonSettings
    solar_radiation_pressure: RadiationPressureSettings
    precession_nutation_threshold: float = bounded(
        unit="arcsec", ge=0, le=1, description="IAU 2006/2000A truncation"
    )
    ellipsoid: EllipsoidSettings
    closed_loop: ClosedLoopSettings
    target_fit: TargetFitSettings
    integration: IntegrationSettings

    def only(self, *terms: str) -> ForceModelSettings:
        """A copy with only ``terms`` switched on (of
        :data:`ovtraj.astro.forces.terms.SWITCHABLE`); gravity is always on."""
        check_term_names(terms)
        update = {
            name: getattr(self, name).model_copy(update={"enabled": name in terms})
            for name in SWITCHABLE
        }
        return self.model_copy(update=update)

    def switched_on(self) -> tuple[str, ...]:
        """The switchable terms whose section says ``enabled``."""
        return tuple(name for name in SWITCHABLE if getattr(self, name).enabled)


@lru_cache(maxsize=1)
def default_force_model() -> ForceModelSettings:
    """The shipped ``configs/force_model.yaml``."""
    from ovtraj.paths import config_path

    return load_model(ForceModelSettings, config_path("force_model.yaml"))
