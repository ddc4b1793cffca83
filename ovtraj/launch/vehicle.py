"""The launcher in SI units, as the ascent dynamics use it.

Built once from a :class:`~ovtraj.config.launch.LauncherConfig`. Solid stages burn
at constant vacuum thrust ``F_vac`` with mass flow ``F_vac / (Isp g0)`` until their
propellant is gone (burn time ``m_p Isp g0 / F_vac``; the configuration's
published burn time is only checked against it); the thrust delivered in the
atmosphere is ``F_vac - p_a A_e`` (Sutton & Biblarz, *Rocket Propulsion
Elements*, 9th ed., eq. 2-14).

Aerodynamics are body-axis coefficients on the reference area ``S``: axial force
``C_A(M)`` and normal force ``C_N = C_N_alpha(M) sin(alpha)`` (first-order
slender-body form, linear in alpha for small angles), each coefficient a monotone
cubic (PCHIP) through the configured Mach points, the wing adding its own
``C_N_alpha,w(M) S_w / S`` during first-stage flight. Lift and drag follow as
``C_L = C_N cos a - C_A sin a`` and ``C_D = C_N sin a + C_A cos a``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import PchipInterpolator

from ovtraj.config.launch import LauncherConfig


@dataclass(frozen=True)
class StageModel:
    name: str
    vacuum_thrust_n: float
    mass_flow_kg_s: float
    burn_time_s: float
    nozzle_exit_area_m2: float
    burnout_drop_kg: float  # inert mass plus whatever leaves with the stage

    @property
    def exhaust_velocity_mps(self) -> float:
        return self.vacuum_thrust_n / self.mass_flow_kg_s


@dataclass(frozen=True)
class AeroModel:
    reference_area_m2: float
    wing_area_ratio: float
    mach: NDArray[np.float64]
    axial: NDArray[np.float64]
    normal_slope: NDArray[np.float64]
    wing_normal_slope: NDArray[np.float64]
    upper_axial_scale: float

    @classmethod
    def from_table(
        cls,
        *,
        mach: NDArray,
        axial: NDArray,
        normal_slope: NDArray,
        wing_normal_slope: NDArray,
        mach_resolution: float,
        **scalars: float,
    ) -> AeroModel:
        """Monotone cubic (PCHIP) through the configured points, resampled finely.

        A smooth curve keeps the fixed-step integration at its order through the
        transonic corners; the resampled table is then read by linear interpolation.
        """
        fine = np.arange(0.0, mach[-1] + 0.5 * mach_resolution, mach_resolution)
        return cls(
            mach=fine,
            axial=PchipInterpolator(mach, axial)(fine),
            normal_slope=PchipInterpolator(mach, normal_slope)(fine),
            wing_normal_slope=PchipInterpolator(mach, wing_normal_slope)(fine),
            **scalars,
        )

    def coefficients(
        self, mach: NDArray[np.float64], *, wing: bool, axial_scale: float
    ) -> tuple[NDArray, NDArray]:
        """``C_A`` and ``C_N_alpha`` (per rad, on the reference area) at ``mach``."""
        ca = axial_scale * np.interp(mach, self.mach, self.axial)
        cna = np.interp(mach, self.mach, self.normal_slope)
        if wing:
            cna = cna + self.wing_area_ratio * np.interp(mach, self.mach, self.wing_normal_slope)
        return ca, cna

    def lift_drag(
        self, alpha_rad: NDArray, mach: NDArray, *, wing: bool, axial_scale: float = 1.0
    ) -> tuple[NDArray, NDArray]:
        """``C_L`` and ``C_D`` at ``alpha_rad`` and ``mach`` (for tables and checks)."""
        ca, cna = self.coefficients(
            np.asarray(mach, dtype=float), wing=wing, axial_scale=axial_scale
        )
        a = np.asarray(alpha_rad, dtype=float)
        cn = cna * np.sin(a)
        return cn * np.cos(a) - ca * np.sin(a), cn * np.sin(a) + ca * np.cos(a)


@dataclass(frozen=True)
class LauncherModel:
    name: str
    stages: tuple[StageModel, ...]
    fairing_mass_kg: float
    fairing_jettison_altitude_m: float
    fairing_earliest_stage: int  # 0-based
    aero: AeroModel
    free_fall_s: float
    separation_coast_s: float
    alpha_drop_rad: float
    max_alpha_rate_rad_s: float
    max_dynamic_pressure_pa: float
    max_axial_load_g: float
    lift_off_mass_without_payload_kg: float

    @classmethod
    def from_config(cls, config: LauncherConfig, *, g0: float) -> LauncherModel:
        stages = tuple(
            StageModel(
                name=s.name,
                vacuum_thrust_n=s.vacuum_thrust_n,
                mass_flow_kg_s=s.mass_flow_kg_s(g0),
                burn_time_s=s.derived_burn_time_s(g0),
                nozzle_exit_area_m2=s.nozzle_exit_area_m2,
                burnout_drop_kg=s.inert_mass_kg + s.jettisoned_with_stage_kg,
            )
            for s in config.stages
        )
        aero = config.aero
        return cls(
            name=config.name,
            stages=stages,
            fairing_mass_kg=config.fairing.mass_kg,
            fairing_jettison_altitude_m=config.fairing.jettison_altitude_km * 1e3,
            fairing_earliest_stage=config.fairing.earliest_stage - 1,
            aero=AeroModel.from_table(
                reference_area_m2=aero.reference_area_m2,
                wing_area_ratio=aero.wing_area_m2 / aero.reference_area_m2,
                mach=np.array(aero.mach),
                axial=np.array(aero.axial_force_coefficient),
                normal_slope=np.array(aero.normal_force_slope_per_rad),
                wing_normal_slope=np.array(aero.wing_normal_force_slope_per_rad),
                upper_axial_scale=aero.axial_force_scale_above_stage_1,
                mach_resolution=config.aero.mach_resolution,
            ),
            free_fall_s=config.free_fall_s,
            separation_coast_s=config.separation_coast_s,
            alpha_drop_rad=math.radians(config.alpha_drop_deg),
            max_alpha_rate_rad_s=math.radians(config.max_alpha_rate_deg_s),
            max_dynamic_pressure_pa=config.limits.max_dynamic_pressure_kpa * 1e3,
            max_axial_load_g=config.limits.max_axial_load_g,
            lift_off_mass_without_payload_kg=config.ignition_masses_kg(0.0)[0],
        )

    def ideal_delta_v_mps(
        self, payload_kg: float, *, fairing_stage: int | None, fairing_burn_time_s: float = 0.0
    ) -> float:
        """Rocket-equation delta-v of the stack, ``sum c ln(m_start / m_end)`` [m/s].

        The fairing leaves ``fairing_burn_time_s`` into the burn of stage
        ``fairing_stage`` (0-based; ``None``: it stays on), which splits that burn
        in two rocket-equation arcs.
        """
        mass = payload_kg + self.lift_off_mass_without_payload_kg
        total = 0.0
        for k, stage in enumerate(self.stages):
            arcs = [stage.burn_time_s]
            if k == fairing_stage:
                split = min(max(fairing_burn_time_s, 0.0), stage.burn_time_s)
                arcs = [split, stage.burn_time_s - split]
            for j, duration in enumerate(arcs):
                burnt = stage.mass_flow_kg_s * duration
                total += stage.exhaust_velocity_mps * math.log(mass / (mass - burnt))
                mass -= burnt
                if j == 0 and len(arcs) == 2:
                    mass -= self.fairing_mass_kg
            mass -= stage.burnout_drop_kg
        return total
