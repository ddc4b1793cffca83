"""The Earth model (gravitational parameter, radius, J2, rotation rate, g0).

The figures live in ``configs/earth.yaml``; this module only gives them a type.
Core functions take the numbers they need as plain floats (``mu``, ``radius``...)
so that a problem stated with another Earth (seed 001 uses its own constants)
only has to pass a different :class:`EarthModel`.
"""

from __future__ import annotations

from dataclasses import dataclass

from pydantic import BaseModel, ConfigDict, Field, field_validator


class EarthModel(BaseModel):
    """Earth constants in SI units."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    mu_m3_s2: float = Field(gt=0, description="gravitational parameter [m^3/s^2]")
    equatorial_radius_m: float = Field(gt=0, description="equatorial (spherical) radius [m]")
    j2: float = Field(ge=0, lt=0.01, description="second zonal harmonic [-]")
    rotation_rate_rad_s: float = Field(ge=0, description="sidereal rotation rate [rad/s]")
    g0_m_s2: float = Field(gt=0, description="standard gravity [m/s^2]")

    @field_validator("*", mode="before")
    @classmethod
    def _not_a_boolean(cls, value: object) -> object:
        # pydantic's lax mode would read YAML's `true` as 1 (configs/earth.yaml is read
        # here, outside the config package's StrictModel).
        if isinstance(value, bool):
            raise ValueError("expected a number, not a boolean")
        return value

    @property
    def mu(self) -> float:
        return self.mu_m3_s2

    @property
    def radius(self) -> float:
        return self.equatorial_radius_m

    @property
    def omega(self) -> float:
        return self.rotation_rate_rad_s


@dataclass(frozen=True)
class EarthConstants:
    """mu [m^3/s^2], equatorial radius [m], J2 [-] (0 when J2 is off), g0 [m/s^2]."""

    mu: float
    radius: float
    j2: float
    g0: float
