"""The compiled entry dynamics with a vehicle, an atmosphere and a landing site bound."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ovtraj.config.physical import default_atmosphere
from ovtraj.reentry import dynamics as dyn
from ovtraj.reentry.inputs import EntryState, ReentryInput
from ovtraj.units import DEG_PER_RAD


@dataclass(frozen=True)
class Flight:
    """One integrated entry (SI; times from the entry epoch)."""

    status: int
    time_s: float
    state: np.ndarray  # r, lon, lat, V, gamma, psi at the end
    max_heat_rate_w_m2: float
    max_heat_rate_time_s: float
    max_load_g: float
    max_load_time_s: float
    max_dynamic_pressure_pa: float
    max_dynamic_pressure_time_s: float
    max_bank_rad: float
    reversals: int
    history: np.ndarray | None  # rows of dynamics.HISTORY_COLUMNS

    @property
    def reached(self) -> bool:
        return self.status == dyn.TERMINAL


class EntryModel:
    """Parameters of :func:`ovtraj.reentry.dynamics.fly` built once per input."""

    def __init__(self, inp: ReentryInput) -> None:
        s = inp.settings
        earth = inp.earth
        vehicle, limits, atm = s.vehicle, s.limits, s.atmosphere
        self.earth = earth
        self.cl = np.array(vehicle.aero.cl, dtype=float)
        self.cd = np.array(vehicle.aero.cd, dtype=float)
        self.mach_nodes = np.array(vehicle.alpha_schedule.mach, dtype=float)
        self.alpha_nodes = np.radians(np.array(vehicle.alpha_schedule.alpha_deg, dtype=float))
        if atm.model == "us76":
            us76 = default_atmosphere()
            nodes = np.arange(0.0, us76.top_altitude_m + 0.5 * atm.table_step_m, atm.table_step_m)
            self.log_rho = np.log(np.asarray(us76.density(nodes), dtype=float))
            self.sound = np.asarray(us76.speed_of_sound(nodes), dtype=float)
        else:
            self.log_rho = np.zeros(2)
            self.sound = np.zeros(2)
        p = np.zeros(dyn.N_PARAMS)
        p[dyn.P_MU] = earth.mu
        p[dyn.P_RADIUS] = earth.radius
        p[dyn.P_OMEGA] = earth.omega if s.integration.earth_rotation else 0.0
        p[dyn.P_G0] = earth.g0_m_s2
        p[dyn.P_MASS_AREA] = vehicle.mass_kg / vehicle.reference_area_m2
        p[dyn.P_ALPHA_SCALE] = DEG_PER_RAD if vehicle.aero.alpha_unit == "deg" else 1.0
        p[dyn.P_ATM_MODEL] = 1.0 if atm.model == "exponential" else 0.0
        p[dyn.P_ATM_STEP] = atm.table_step_m
        p[dyn.P_RHO0] = atm.density0_kg_m3
        p[dyn.P_SCALE_HEIGHT] = atm.scale_height_km * 1e3
        p[dyn.P_SOUND] = atm.speed_of_sound_mps
        p[dyn.P_KQ] = limits.heat_rate_coefficient
        p[dyn.P_NQ] = limits.heat_rate_exponent
        p[dyn.P_SIGMA_MAX] = math.radians(limits.max_bank_deg)
        p[dyn.P_V_START] = inp.entry.speed_mps
        p[dyn.P_V_END] = s.terminal.speed_mps
        p[dyn.P_TARGET_LAT] = inp.target_latitude_rad
        p[dyn.P_TARGET_LON] = inp.target_longitude_rad
        p[dyn.P_CORRIDOR_MIN] = math.radians(s.guidance.corridor_min_deg)
        p[dyn.P_CORRIDOR_MAX] = math.radians(s.guidance.corridor_max_deg)
        p[dyn.P_CORRIDOR_RANGE] = s.guidance.corridor_range_km * 1e3
        p[dyn.P_STEP] = s.integration.step_s
        p[dyn.P_MAX_TIME] = s.integration.max_time_s
        p[dyn.P_SKIP_RADIUS] = (
            earth.radius + inp.entry.altitude_m + s.integration.skip_altitude_margin_km * 1e3
        )
        p[dyn.P_GUIDED] = 1.0
        p[dyn.P_BANK_SIGN] = 1.0
        self.params = p
        self.tables: dyn.Tables = (
            self.cl,
            self.cd,
            self.mach_nodes,
            self.alpha_nodes,
            self.log_rho,
            self.sound,
        )
        self.x0 = initial_state(inp.entry, earth.radius)
        self.flights = 0

    def fly(
        self,
        sigma0_rad: float,
        sigma1_rad: float,
        *,
        record: bool = False,
        guided: bool = True,
        bank_sign: float = 1.0,
        x0: np.ndarray | None = None,
    ) -> Flight:
        p = self.params.copy()
        p[dyn.P_SIGMA0], p[dyn.P_SIGMA1] = sigma0_rad, sigma1_rad
        p[dyn.P_GUIDED] = 1.0 if guided else 0.0
        p[dyn.P_BANK_SIGN] = bank_sign
        self.flights += 1
        status, t, x, maxima, reversals, history, n = dyn.fly(
            self.x0 if x0 is None else np.asarray(x0, dtype=float),
            p,
            self.tables,
            record,
        )
        return Flight(
            status=int(status),
            time_s=float(t),
            state=np.array(x),
            max_heat_rate_w_m2=float(maxima[0]),
            max_heat_rate_time_s=float(maxima[1]),
            max_load_g=float(maxima[2]),
            max_load_time_s=float(maxima[3]),
            max_dynamic_pressure_pa=float(maxima[4]),
            max_dynamic_pressure_time_s=float(maxima[5]),
            max_bank_rad=float(maxima[6]),
            reversals=int(reversals),
            history=np.array(history[:n]) if record else None,
        )


def initial_state(entry: EntryState, radius_m: float) -> np.ndarray:
    return np.array(
        [
            radius_m + entry.altitude_m,
            entry.longitude_rad,
            entry.latitude_rad,
            entry.speed_mps,
            entry.fpa_rad,
            entry.heading_rad,
        ]
    )
