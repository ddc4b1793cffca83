"""The optimal-entry problem in SI, built from its YAML config and checked for posability.

:func:`load_optimal_entry` reads a file (:mod:`ovtraj.config.optimal_entry`), converts
degrees, km, kPa and kW/m^2 to SI once, and refuses problems that cannot be posed, with
one line per offending field (:class:`ovtraj.config.ConfigError`):

* the initial state outside the state bounds;
* terminal bounds that do not meet the state bounds;
* a terminal energy that is not below the initial energy (an unpowered vehicle only
  loses specific energy ``E = V^2 / 2 + U(r)``; seed 001 eq. 8);
* altitude bounds outside the US76 range, a guess angle of attack outside its bounds.

Specific energy uses the potential ``U = mu / R - mu / r`` (inverse-square gravity, zero
on the ground as in seed eq. 8) or ``U = g0 h`` (constant gravity), so that
``dE/dt = -V D`` without Earth rotation (seed eq. 9).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ovtraj.astro.atmosphere import ExponentialAtmosphere, US76Atmosphere
from ovtraj.config.base import ConfigError
from ovtraj.config.optimal_entry import (
    BoundConfig,
    OptimalEntryConfig,
    load_optimal_entry_config,
    optimal_entry_config_from_dict,
)
from ovtraj.config.physical import default_atmosphere, default_earth
from ovtraj.studies.optimal_entry.atmosphere import (
    NlpAtmosphere,
    exponential_atmosphere,
    us76_atmosphere,
)
from ovtraj.studies.optimal_entry.nlp import NlpSettings
from ovtraj.units import DEG_PER_RAD, RAD_PER_DEG

__all__ = [
    "STATE_KEYS",
    "EntryProblem",
    "entry_problem",
    "load_optimal_entry",
    "optimal_entry_from_dict",
]

# Order of the time-domain state everywhere in this package.
STATE_KEYS = ("altitude", "longitude", "latitude", "speed", "fpa", "heading")
_CONFIG_FIELD = {
    "altitude": "altitude_km",
    "longitude": "longitude_deg",
    "latitude": "latitude_deg",
    "speed": "speed_mps",
    "fpa": "fpa_deg",
    "heading": "heading_deg",
}
_TO_SI = {
    "altitude": 1e3,
    "longitude": RAD_PER_DEG,
    "latitude": RAD_PER_DEG,
    "speed": 1.0,
    "fpa": RAD_PER_DEG,
    "heading": RAD_PER_DEG,
}


@dataclass(frozen=True)
class EntryProblem:
    """An optimal-entry problem in SI (rad, m, s, kg); see the module notes."""

    config: OptimalEntryConfig
    source: str
    # Earth
    mu: float
    radius: float
    omega: float  # 0 when the Earth does not rotate
    g0: float
    gravity: str
    # vehicle and aerodynamics
    mass: float
    area: float
    cl: NDArray[np.float64]  # c[i][j] alpha^i Mach^j, alpha in the config's unit
    cd: NDArray[np.float64]
    alpha_scale: float  # alpha [rad] times this = alpha in the polynomial's unit
    # atmosphere
    atmosphere: US76Atmosphere | ExponentialAtmosphere
    atmosphere_top_m: float
    nlp_atmosphere: NlpAtmosphere
    # states: (h, lon, lat, V, gamma, psi)
    initial_state: NDArray[np.float64]
    state_lower: NDArray[np.float64]
    state_upper: NDArray[np.float64]
    final_lower: NDArray[np.float64]
    final_upper: NDArray[np.float64]
    # controls (alpha, bank) [rad], rate limits [rad/s] or None
    control_lower: NDArray[np.float64]
    control_upper: NDArray[np.float64]
    control_rate: tuple[float | None, float | None]
    # path limits (None: not constrained)
    max_load_g: float | None
    load_definition: str
    max_dynamic_pressure: float | None  # Pa
    heat_coefficient: float | None
    heat_density_exponent: float
    heat_speed_exponent: float
    heat_alpha_polynomial: NDArray[np.float64]
    max_heat_rate: float | None  # W/m^2
    # task
    objective: str
    independent: str
    method: str
    segments: int
    nodes_per_segment: int
    final_time_bounds: tuple[float, float]
    solver: NlpSettings

    @property
    def name(self) -> str:
        return self.config.name

    def potential(self, h: Any) -> Any:
        """Specific potential energy [J/kg], zero on the ground (seed eq. 8)."""
        if self.gravity == "constant":
            return self.g0 * h
        return self.mu / self.radius - self.mu / (self.radius + h)

    def energy(self, h: Any, v: Any) -> Any:
        """Specific energy ``V^2 / 2 + U(h)`` [J/kg]."""
        return 0.5 * v * v + self.potential(h)

    @property
    def initial_energy(self) -> float:
        return float(self.energy(self.initial_state[0], self.initial_state[3]))

    def terminal_energy_bounds(self) -> tuple[float, float]:
        """Lowest and highest terminal energy the terminal and state bounds allow [J/kg]."""
        lo, hi = self.final_lower, self.final_upper
        e_lo = float(self.energy(lo[0], max(lo[3], 0.0)))
        e_hi = float(self.energy(hi[0], hi[3]))
        return e_lo, e_hi

    @property
    def terminal_energy_fixed(self) -> bool:
        lo, hi = self.final_lower, self.final_upper
        return bool(lo[0] == hi[0] and lo[3] == hi[3])

    def with_options(self, **changes: Any) -> EntryProblem:
        """The same problem with transcription or solver settings replaced."""
        return replace(self, **changes)


def _interval(bound: BoundConfig | None, key: str) -> tuple[float, float]:
    if bound is None:
        return -math.inf, math.inf
    lo, hi = bound.interval()
    return lo * _TO_SI[key], hi * _TO_SI[key]


def _fmt(value: float, key: str) -> str:
    return f"{value / _TO_SI[key]:g}"


def entry_problem(config: OptimalEntryConfig, source: str = "") -> EntryProblem:
    """Convert a validated config to SI and check that the problem can be posed.

    Every check adds its line to the refusal, in the order of the config's sections; the
    terminal energy is checked once the rest stands (it needs a posable problem).
    """
    problems: list[str] = []
    states = _states(config, problems)
    atmosphere = _atmosphere(config, states["state_lower"], states["state_upper"], problems)
    controls = _controls(config, problems)
    if config.objective == "min_heat_load" and config.path.heat_rate is None:
        problems.append(
            "objective = 'min_heat_load': needs path.heat_rate (the heat-rate law to integrate)"
        )
    problem = EntryProblem(
        config=config,
        source=source,
        **_earth(config),
        **_vehicle(config),
        **atmosphere,
        **states,
        **controls,
        **_path_limits(config),
        **_task(config),
    )
    if not problems:
        problems.extend(_energy_problems(problem))
    if problems:
        raise ConfigError(problems, source)
    return problem


def _earth(config: OptimalEntryConfig) -> dict[str, Any]:
    """mu, radius, rotation rate (0 when the Earth does not rotate), g0 and the gravity
    model: the config's, or the project's Earth where it leaves them out."""
    earth = default_earth()
    e = config.earth
    omega_value = e.rotation_rate_rad_s if e.rotation_rate_rad_s is not None else earth.omega
    return {
        "mu": e.mu_m3_s2 if e.mu_m3_s2 is not None else earth.mu,
        "radius": e.radius_m if e.radius_m is not None else earth.radius,
        "omega": omega_value if e.rotating else 0.0,
        "g0": e.g0_m_s2 if e.g0_m_s2 is not None else earth.g0_m_s2,
        "gravity": e.gravity,
    }


def _states(config: OptimalEntryConfig, problems: list[str]) -> dict[str, NDArray[np.float64]]:
    """The initial state, the state bounds and the terminal bounds (within the state
    bounds) in SI; the initial state outside its bounds and terminal bounds that do not
    meet them are refused in ``problems``."""
    sb = config.state_bounds
    state_lower = np.array([getattr(sb, _CONFIG_FIELD[k])[0] * _TO_SI[k] for k in STATE_KEYS])
    state_upper = np.array([getattr(sb, _CONFIG_FIELD[k])[1] * _TO_SI[k] for k in STATE_KEYS])
    ini = config.initial
    initial = np.array([getattr(ini, _CONFIG_FIELD[k]) * _TO_SI[k] for k in STATE_KEYS])
    for i, k in enumerate(STATE_KEYS):
        if not state_lower[i] <= initial[i] <= state_upper[i]:
            problems.append(
                f"initial.{_CONFIG_FIELD[k]} = {_fmt(initial[i], k)}: outside "
                f"state_bounds.{_CONFIG_FIELD[k]} [{_fmt(state_lower[i], k)}, "
                f"{_fmt(state_upper[i], k)}]"
            )
    final_lower, final_upper = state_lower.copy(), state_upper.copy()
    for i, k in enumerate(STATE_KEYS):
        lo, hi = _interval(getattr(config.terminal, _CONFIG_FIELD[k]), k)
        final_lower[i] = max(final_lower[i], lo)
        final_upper[i] = min(final_upper[i], hi)
        if final_lower[i] > final_upper[i]:
            problems.append(
                f"terminal.{_CONFIG_FIELD[k]}: [{_fmt(lo, k)}, {_fmt(hi, k)}] does not meet "
                f"state_bounds.{_CONFIG_FIELD[k]} [{_fmt(state_lower[i], k)}, "
                f"{_fmt(state_upper[i], k)}]"
            )
    if config.transcription.independent == "energy" and state_lower[3] <= 0.0:
        problems.append(
            "state_bounds.speed_mps: the energy formulation needs a positive lower speed "
            "(the speed is recovered from the energy by a square root)"
        )
    return {
        "initial_state": initial,
        "state_lower": state_lower,
        "state_upper": state_upper,
        "final_lower": final_lower,
        "final_upper": final_upper,
    }


def _atmosphere(
    config: OptimalEntryConfig,
    state_lower: NDArray[np.float64],
    state_upper: NDArray[np.float64],
    problems: list[str],
) -> dict[str, Any]:
    """The library's atmosphere (numpy), its top and the NLP's expressions of it; US76
    refuses altitude bounds outside its range."""
    atm = config.atmosphere
    top = state_upper[0]
    if atm.model == "us76":
        model: US76Atmosphere | ExponentialAtmosphere = default_atmosphere()
        atmosphere_top = model.top_altitude_m
        if state_lower[0] < 0.0 or top > model.top_altitude_m:
            problems.append(
                f"state_bounds.altitude_km: US76 is defined on [0, "
                f"{model.top_altitude_m / 1e3:g}] km"
            )
        nlp_atm = us76_atmosphere(
            model, min(top, model.top_altitude_m), atm.upper_sound_step_km * 1e3
        )
    else:
        assert atm.density0_kg_m3 and atm.scale_height_km and atm.speed_of_sound_mps
        model = ExponentialAtmosphere(
            atm.density0_kg_m3, atm.scale_height_km * 1e3, atm.speed_of_sound_mps
        )
        atmosphere_top = math.inf
        nlp_atm = exponential_atmosphere(
            atm.density0_kg_m3, atm.scale_height_km * 1e3, atm.speed_of_sound_mps
        )
    return {"atmosphere": model, "atmosphere_top_m": atmosphere_top, "nlp_atmosphere": nlp_atm}


def _controls(config: OptimalEntryConfig, problems: list[str]) -> dict[str, Any]:
    """The bounds and rate limits of (alpha, bank) in rad and rad/s; a guess outside the
    bounds is refused in ``problems``."""
    c = config.controls
    rates = tuple(
        None if ctl.max_rate_deg_s is None else math.radians(ctl.max_rate_deg_s)
        for ctl in (c.alpha, c.bank)
    )
    g = config.guess
    if g.alpha_deg is not None and not c.alpha.lower_deg <= g.alpha_deg <= c.alpha.upper_deg:
        problems.append(
            f"guess.alpha_deg = {g.alpha_deg:g}: outside controls.alpha "
            f"[{c.alpha.lower_deg:g}, {c.alpha.upper_deg:g}]"
        )
    if not c.bank.lower_deg <= g.bank_deg <= c.bank.upper_deg:
        problems.append(
            f"guess.bank_deg = {g.bank_deg:g}: outside controls.bank "
            f"[{c.bank.lower_deg:g}, {c.bank.upper_deg:g}]"
        )
    return {
        "control_lower": np.radians([c.alpha.lower_deg, c.bank.lower_deg]),
        "control_upper": np.radians([c.alpha.upper_deg, c.bank.upper_deg]),
        "control_rate": (rates[0], rates[1]),
    }


def _vehicle(config: OptimalEntryConfig) -> dict[str, Any]:
    """Mass, reference area and the lift and drag polynomials with their alpha unit."""
    aero = config.vehicle.aero
    return {
        "mass": config.vehicle.mass_kg,
        "area": config.vehicle.reference_area_m2,
        "cl": np.array(aero.cl, dtype=float),
        "cd": np.array(aero.cd, dtype=float),
        "alpha_scale": DEG_PER_RAD if aero.alpha_unit == "deg" else 1.0,
    }


def _path_limits(config: OptimalEntryConfig) -> dict[str, Any]:
    """The load, dynamic-pressure and heat-rate limits in SI (None: not constrained) and
    the heat-rate law."""
    path = config.path
    heat = path.heat_rate
    return {
        "max_load_g": path.max_load_g,
        "load_definition": path.load_definition,
        "max_dynamic_pressure": None
        if path.max_dynamic_pressure_kpa is None
        else path.max_dynamic_pressure_kpa * 1e3,
        "heat_coefficient": None if heat is None else heat.coefficient,
        "heat_density_exponent": 0.0 if heat is None else heat.density_exponent,
        "heat_speed_exponent": 0.0 if heat is None else heat.speed_exponent,
        "heat_alpha_polynomial": np.array([1.0] if heat is None else heat.alpha_polynomial),
        "max_heat_rate": None if heat is None else heat.max_kw_m2 * 1e3,
    }


def _task(config: OptimalEntryConfig) -> dict[str, Any]:
    """The objective, the transcription and the solver's settings."""
    t = config.transcription
    s = config.solver
    return {
        "objective": config.objective,
        "independent": t.independent,
        "method": t.method,
        "segments": t.segments,
        "nodes_per_segment": t.nodes_per_segment,
        "final_time_bounds": t.final_time_bounds_s,
        "solver": NlpSettings(
            backend=s.backend,
            tolerance=s.tolerance,
            constraint_tolerance=s.constraint_tolerance,
            max_iterations=s.max_iterations,
            linear_solver=s.linear_solver,
            barrier_strategy=s.barrier_strategy,
            print_level=s.print_level,
            expand=s.expand,
            time_limit_s=s.time_limit_s,
        ),
    }


def _energy_problems(problem: EntryProblem) -> list[str]:
    """An unpowered entry only loses energy: the lowest terminal energy must lie below
    the initial one."""
    e0 = problem.initial_energy
    e_lo, _ = problem.terminal_energy_bounds()
    if e_lo < e0:
        return []
    return [
        f"terminal.altitude_km, terminal.speed_mps: the lowest terminal energy they "
        f"allow ({e_lo / 1e6:.6g} MJ/kg) is not below the initial energy "
        f"({e0 / 1e6:.6g} MJ/kg, initial.altitude_km and initial.speed_mps); an "
        f"unpowered entry only loses energy"
    ]


def load_optimal_entry(path: str | Path) -> EntryProblem:
    """Read, validate and convert an optimal-entry YAML file (e.g. the published case)."""
    config = load_optimal_entry_config(path)
    return entry_problem(config, str(path))


def optimal_entry_from_dict(data: Any, source: str = "") -> EntryProblem:
    """The same from a mapping (tests, scripted studies)."""
    return entry_problem(optimal_entry_config_from_dict(data, source), source)
