"""The equations of motion of the high-fidelity model: the terms of :class:`ForceTerms`
summed, as heyoka expressions (the state x, y, z, vx, vy, vz in TEME, m and m/s).

Runtime parameters (:data:`PARAMETERS`, in this order): the origin's TT centuries and
UTC day of year, the spacecraft's C_D A / m and C_R A / m [m^2/kg], and the radius [m]
of the floor event (:mod:`.propagator`). Everything else is compiled in, so a
:class:`ForceTerms` is the key of a compiled integrator.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any, Literal

import heyoka as hy

from ovtraj.astro.forces.drag import (
    SpaceWeather,
    drag_acceleration,
    geodetic,
    thermosphere_density,
)
from ovtraj.astro.forces.earth_data import earth_orientation_data
from ovtraj.astro.forces.gravity_field import egm2008_acceleration, teme_to_itrs
from ovtraj.astro.forces.radiation_pressure import (
    lit_fraction,
    radiation_pressure_acceleration,
    shadow_argument,
)
from ovtraj.astro.forces.terms import FORCE_TERMS, check_term_names, needed
from ovtraj.astro.forces.third_body import moon_position, sun_position, third_body_acceleration
from ovtraj.astro.forces.time_scales import tt_centuries_expression
from ovtraj.astro.propagation.gravity import two_body_j2_acceleration
from ovtraj.units import DAYS_PER_JULIAN_CENTURY, S_PER_DAY

__all__ = [
    "KERNELS",
    "PARAMETERS",
    "ForceTerms",
    "Symbols",
    "accelerations",
    "equations",
    "step_boundaries",
    "symbols",
]

PARAMETERS = ("tt0", "doy0", "ballistic_m2_kg", "radiation_m2_kg", "floor_radius_m")
_STATE = ("x", "y", "z", "vx", "vy", "vz")


@dataclass(frozen=True)
class ForceTerms:
    """What the orbit is flown under; ``None`` switches a term off. SI units.

    ``gravity``: ``egm2008`` to ``degree`` x ``order`` or ``j2`` (point mass + J2 with
    ``mu``, ``radius``, ``j2``: the chain's field). ``drag_model``: ``nrlmsise00``,
    ``jb08`` or None; ``weather``: ``bundled`` or ``constant`` (``f107``, ``f107a``,
    ``ap``; ``jb08_indices`` in both). ``sun_mu`` / ``moon_mu``: None leaves the body out
    (the Sun's position is still built for radiation pressure). ``radiation``: (pressure
    at 1 AU [N/m^2], the AU [m], the Sun's radius [m], the shadow's sharpness, the
    shadow argument at which a step ends, :func:`step_boundaries`) or None.
    """

    gravity: Literal["egm2008", "j2"]
    degree: int
    order: int
    mu: float
    radius: float
    j2: float
    omega: float
    drag_model: str | None
    weather: Literal["bundled", "constant"]
    f107: float
    f107a: float
    ap: float
    jb08_indices: tuple[float, ...]
    sun_mu: float | None
    vsop_threshold: float
    moon_mu: float | None
    elp_threshold: float
    radiation: tuple[float, float, float, float, float] | None
    astronomical_unit_m: float
    precession_threshold: float
    eop_extrapolation_days: float
    ellipsoid_radius_m: float
    ellipsoid_ecc2: float

    def only(self, *terms: str) -> ForceTerms:
        """A copy with the switchable terms not named here switched off (``ValueError``
        for a name that is not a switchable term of :data:`.terms.FORCE_TERMS`)."""
        check_term_names(terms)
        return replace(
            self,
            **{
                term.switch: getattr(self, term.switch) if term.name in terms else None
                for term in FORCE_TERMS
                if term.switch is not None
            },
        )

    def switched_on(self) -> tuple[str, ...]:
        """The names of the terms on, in the order of :data:`.terms.FORCE_TERMS`."""
        return tuple(
            term.name
            for term in FORCE_TERMS
            if term.switch is None or getattr(self, term.switch) is not None
        )


@dataclass(frozen=True)
class Symbols:
    """The state variables, the parameters by name and the time arguments."""

    state: tuple[Any, ...]
    par: dict[str, Any]
    tt: Any  # TT Julian centuries since J2000
    day_of_year: Any  # UTC days since 1 January


def symbols() -> Symbols:
    state = tuple(hy.make_vars(*_STATE))
    par = {name: hy.par[i] for i, name in enumerate(PARAMETERS)}
    return Symbols(
        state=state,
        par=par,
        tt=tt_centuries_expression(par["tt0"], hy.time),
        day_of_year=par["doy0"] + hy.time / S_PER_DAY,
    )


def _weather(terms: ForceTerms, tt: Any) -> SpaceWeather:
    jb08 = tuple(hy.expression(v) for v in terms.jb08_indices)
    if terms.weather == "constant":
        return SpaceWeather(
            hy.expression(terms.f107), hy.expression(terms.f107a), hy.expression(terms.ap), jb08
        )
    data = hy.sw_data()
    # NRLMSISE-00's F10.7 is the previous day's (Picone et al. 2002).
    day = 1.0 / DAYS_PER_JULIAN_CENTURY
    return SpaceWeather(
        hy.model.f107(tt - day, data),
        hy.model.f107a_center81(tt, data),
        hy.model.Ap_avg(tt, data),
        jb08,
    )


def _sun(terms: ForceTerms, s: Symbols, eop: Any) -> list[Any]:
    return sun_position(
        s.tt,
        astronomical_unit_m=terms.astronomical_unit_m,
        threshold=terms.vsop_threshold,
        eop=eop,
        precession_threshold=terms.precession_threshold,
    )


def step_boundaries(terms: ForceTerms, s: Symbols) -> list[Any]:
    """Functions whose roots a Taylor step must end at: the edges of the smoothed shadow
    (:mod:`ovtraj.astro.forces.radiation_pressure`), where the flat tanh would let a step
    stride over the penumbra. None without radiation pressure."""
    if terms.radiation is None:
        return []
    _, _, sun_radius, sharpness, edge = terms.radiation
    eop = earth_orientation_data(terms.eop_extrapolation_days)
    argument = shadow_argument(
        list(s.state[:3]),
        _sun(terms, s, eop),
        earth_radius_m=terms.radius,
        sun_radius_m=sun_radius,
        sharpness=sharpness,
    )
    return [argument - edge, argument + edge]


@dataclass
class _Place:
    """What the kernels share at one state: its position and velocity [m, m/s], the Earth
    orientation data, and the Sun's position, built once when a term on needs it."""

    r: list[Any]
    v: list[Any]
    eop: Any
    sun: list[Any] | None


Kernel = Callable[[ForceTerms, Symbols, _Place], list[Any]]


def _gravity(terms: ForceTerms, s: Symbols, at: _Place) -> list[Any]:
    if terms.gravity == "egm2008":
        return egm2008_acceleration(at.r, s.tt, degree=terms.degree, order=terms.order, eop=at.eop)
    return list(
        two_body_j2_acceleration(*at.r, mu=terms.mu, radius=terms.radius, j2=terms.j2, sqrt=hy.sqrt)
    )


def _drag(terms: ForceTerms, s: Symbols, at: _Place) -> list[Any]:
    where = geodetic(
        teme_to_itrs(at.r, s.tt, at.eop),
        equatorial_radius_m=terms.ellipsoid_radius_m,
        eccentricity_squared=terms.ellipsoid_ecc2,
    )
    density = thermosphere_density(where, s.day_of_year, _weather(terms, s.tt), terms.drag_model)
    return drag_acceleration(at.r, at.v, density, s.par["ballistic_m2_kg"], terms.omega)


def _sun_attraction(terms: ForceTerms, s: Symbols, at: _Place) -> list[Any]:
    return third_body_acceleration(at.r, at.sun, terms.sun_mu)


def _moon_attraction(terms: ForceTerms, s: Symbols, at: _Place) -> list[Any]:
    moon = moon_position(
        s.tt,
        threshold=terms.elp_threshold,
        eop=at.eop,
        precession_threshold=terms.precession_threshold,
    )
    return third_body_acceleration(at.r, moon, terms.moon_mu)


def _radiation_pressure(terms: ForceTerms, s: Symbols, at: _Place) -> list[Any]:
    pressure, au, sun_radius, sharpness, _ = terms.radiation
    lit = lit_fraction(
        at.r, at.sun, earth_radius_m=terms.radius, sun_radius_m=sun_radius, sharpness=sharpness
    )
    return radiation_pressure_acceleration(
        at.r, at.sun, s.par["radiation_m2_kg"], lit, pressure_n_m2=pressure, astronomical_unit_m=au
    )


KERNELS: dict[str, Kernel] = {
    "gravity": _gravity,
    "drag": _drag,
    "sun": _sun_attraction,
    "moon": _moon_attraction,
    "solar_radiation_pressure": _radiation_pressure,
}
"""Each term's acceleration [m/s^2] in TEME, by the name of :data:`.terms.FORCE_TERMS`."""


def accelerations(terms: ForceTerms, s: Symbols) -> dict[str, list[Any]]:
    """Each switched-on term's acceleration [m/s^2] in TEME, by name, in the order of
    :data:`.terms.FORCE_TERMS`."""
    on = terms.switched_on()
    eop = earth_orientation_data(terms.eop_extrapolation_days)
    sun = _sun(terms, s, eop) if needed("sun_position", on) else None
    at = _Place(list(s.state[:3]), list(s.state[3:]), eop, sun)
    return {name: KERNELS[name](terms, s, at) for name in on}


def equations(terms: ForceTerms, s: Symbols) -> list[tuple[Any, Any]]:
    """(variable, derivative) pairs of the state under the sum of the terms."""
    parts = accelerations(terms, s)
    total = [hy.sum([part[i] for part in parts.values()]) for i in range(3)]
    x, y, z, vx, vy, vz = s.state
    return [(x, vx), (y, vy), (z, vz), (vx, total[0]), (vy, total[1]), (vz, total[2])]
