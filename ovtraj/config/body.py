"""A spacecraft as drag and solar radiation pressure see it: the cannonball
figures of the high-fidelity force model (``ovtraj.astro.forces``)."""

from __future__ import annotations

from ovtraj.config.base import StrictModel, bounded


class BodyConfig(StrictModel):
    """Cross-sections and coefficients of a cannonball model (mean over attitudes)."""

    drag_area_m2: float = bounded(unit="m^2", ge=0, le=1.0e4)
    drag_coefficient: float = bounded(ge=0, le=10, description="free-molecular flow: ~2.2")
    srp_area_m2: float = bounded(unit="m^2", ge=0, le=1.0e4)
    reflectivity_coefficient: float = bounded(ge=1, le=2, description="C_R: 1 absorbs, 2 mirrors")

    def ballistic_m2_kg(self, mass_kg: float) -> float:
        """C_D A / m [m^2/kg], the drag's factor."""
        return self.drag_coefficient * self.drag_area_m2 / mass_kg

    def radiation_m2_kg(self, mass_kg: float) -> float:
        """C_R A / m [m^2/kg], the radiation pressure's factor."""
        return self.reflectivity_coefficient * self.srp_area_m2 / mass_kg


class TargetBodyConfig(BodyConfig):
    """The target's body, with its mass (the vehicle's is ``vehicle.mass_kg``)."""

    mass_kg: float = bounded(unit="kg", gt=0, le=1.0e7)
