"""Density and speed of sound as CasADi expressions, for exact NLP derivatives.

* **Exponential**: ``rho = rho0 exp(-h / H)``, constant speed of sound.
* **US76** below 86 km is the standard's closed form, rebuilt symbolically from the
  layer arrays of :class:`ovtraj.astro.atmosphere.US76Atmosphere` (NOAA-S/T 76-1562:
  geopotential height eq. 18, linear molecular-scale temperature eq. 23, pressure
  eqs. 33a/33b, density eq. 42, speed of sound eq. 50). No fit: values equal the
  library's to round-off. The density is continuous, its slope jumps by a few percent
  at the layer bases (the lapse rate changes there); IPOPT copes with such kinks.
  Above 86 km the library's density is log-linear between its nodes, so the NLP uses the
  same nodes; the speed of sound there (a function of the kinetic temperature) is
  sampled from the library every ``upper_sound_step_m`` and interpolated linearly. The
  upper part is built only when the problem's altitude bound exceeds 86 km.

Each layer's formula is evaluated at the altitude clamped into that layer, so the
branches not taken stay finite (a negative temperature raised to a power would give
NaN derivatives through ``if_else``).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from ovtraj.astro.atmosphere import US76Atmosphere

__all__ = ["NlpAtmosphere", "exponential_atmosphere", "us76_atmosphere"]


@dataclass(frozen=True)
class NlpAtmosphere:
    """``evaluate(h)`` -> ``(rho [kg/m^3], a [m/s])`` for a CasADi altitude ``h`` [m]."""

    kind: str
    _us76: US76Atmosphere | None = None
    _rho0: float = 0.0
    _scale_height: float = 0.0
    _sound: float = 0.0
    _top_m: float = 0.0
    _sound_step_m: float = 0.0

    def evaluate(self, h: ca.SX) -> tuple[ca.SX, ca.SX]:
        if self.kind == "exponential":
            return self._rho0 * ca.exp(-h / self._scale_height), self._sound + 0.0 * h
        assert self._us76 is not None
        return _us76_expressions(self._us76, h, self._top_m, self._sound_step_m)


def exponential_atmosphere(
    rho0_kg_m3: float, scale_height_m: float, speed_of_sound_mps: float
) -> NlpAtmosphere:
    return NlpAtmosphere(
        "exponential",
        _rho0=rho0_kg_m3,
        _scale_height=scale_height_m,
        _sound=speed_of_sound_mps,
    )


def us76_atmosphere(model: US76Atmosphere, top_m: float, sound_step_m: float) -> NlpAtmosphere:
    """US76 for altitudes up to ``top_m`` [m] (the problem's altitude bound)."""
    return NlpAtmosphere("us76", _us76=model, _top_m=top_m, _sound_step_m=sound_step_m)


def _us76_expressions(
    model: US76Atmosphere, z: ca.SX, top_m: float, sound_step_m: float
) -> tuple[ca.SX, ca.SX]:
    table = model.table
    r0 = table.earth_radius_m
    gas = table.gas_constant_J_kmol_K
    m0 = table.sea_level_molecular_weight_kg_kmol
    gamma = table.ratio_of_specific_heats
    k = table.geopotential_gravity_m_s2 * m0 / gas  # g0' M0 / R* [K/m']
    bases = np.asarray(model.layer_base_geopotential_height_m)
    z7 = model.lower_region_top_altitude_m
    h7 = r0 * z7 / (r0 + z7)
    tops = np.append(bases[1:], h7)

    geopotential = r0 * z / (r0 + z)
    rho_lower = None
    sound_lower = None
    # Built from the top layer down so that each if_else tests one base.
    for i in reversed(range(len(bases))):
        hb, lapse = float(bases[i]), float(model.layer_lapse_rate_K_per_m[i])
        tb, pb = float(model.layer_base_temperature_K[i]), float(model.layer_base_pressure_Pa[i])
        dh = ca.fmin(ca.fmax(geopotential, hb), float(tops[i])) - hb
        if lapse == 0.0:
            temperature = tb + 0.0 * dh
            pressure = pb * ca.exp(-k * dh / tb)
        else:
            temperature = tb + lapse * dh
            pressure = pb * (tb / temperature) ** (k / lapse)
        rho = pressure * m0 / (gas * temperature)
        sound = ca.sqrt(gamma * gas * temperature / m0)
        if rho_lower is None:
            rho_lower, sound_lower = rho, sound
        else:
            above = geopotential >= float(tops[i])
            rho_lower = ca.if_else(above, rho_lower, rho)
            sound_lower = ca.if_else(above, sound_lower, sound)
    assert rho_lower is not None and sound_lower is not None
    if top_m <= z7:
        return rho_lower, sound_lower

    # Above 86 km: the library's own log-linear density nodes, sampled speed of sound.
    top = min(top_m, model.top_altitude_m)
    nodes = np.asarray(model.node_altitude_m)
    keep = int(np.searchsorted(nodes, top, side="left")) + 1
    node_z = nodes[: max(keep, 2)]
    node_log_rho = np.asarray(model.node_log_density)[: len(node_z)]
    rho_upper = ca.exp(ca.pw_lin(z, ca.DM(node_z), ca.DM(node_log_rho)))
    grid = np.arange(z7, top + sound_step_m, sound_step_m)
    grid = grid[grid <= model.top_altitude_m]
    if len(grid) < 2:
        grid = np.array([z7, min(z7 + sound_step_m, model.top_altitude_m)])
    sound_grid = np.asarray(model.speed_of_sound(grid), dtype=float)
    sound_upper = ca.pw_lin(z, ca.DM(grid), ca.DM(sound_grid))
    upper = z >= z7
    return ca.if_else(upper, rho_upper, rho_lower), ca.if_else(upper, sound_upper, sound_lower)
