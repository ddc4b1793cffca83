"""Earth atmosphere: U.S. Standard Atmosphere 1976 and a pure exponential model.

Altitudes are geometric heights above a spherical Earth, in metres (SPEC "Conventions");
results are SI: kg/m^3, K, Pa, m/s. Every function takes a scalar or an array and returns a
float or an array of the same shape.

U.S. Standard Atmosphere, 1976 (NOAA-S/T 76-1562, "US76"), figures in
``configs/atmosphere_us76.yaml``:

* **0-86 km** is the standard itself. Geopotential height ``H = r0 Z / (r0 + Z)`` (eq. 18);
  seven layers of linear molecular-scale temperature ``T_M`` in ``H`` (eq. 23, Table 4);
  pressure from the hydrostatic equation in closed form, eq. (33a) in gradient layers and
  eq. (33b) in isothermal ones; density ``rho = P M0 / (R* T_M)`` (eq. 42); speed of sound
  ``a = sqrt(gamma R* T_M / M0)`` (eq. 50). Layer base temperatures and pressures are
  computed from the sea-level values, so the profile is continuous.
* **86-1000 km density** is piecewise exponential, as SPEC allows: ``ln rho`` is linear in
  altitude between density nodes of the standard (Table I; the YAML says how each was
  obtained), i.e. each interval is an exponential with the scale height its two nodes
  imply. The 86 km node is the lower model's value there, so density is continuous.
  Within 0.5 % of the standard.
* **Temperature** is the kinetic temperature ``T``: ``T_M M / M0`` below 86 km (the ratio
  of Table 8, unity below 80 km) and the standard's closed forms above (Table 5):
  isothermal to 91 km, an ellipse to 110 km, +12 K/km to 120 km, then an exponential
  approach to ``T_inf = 1000 K``. Each segment starts from the end value of the one below
  (which reproduces the standard's 186.8673 K, 240 K and 360 K to 2e-6), so ``T`` is
  continuous.
* **Speed of sound above 86 km** is not defined by the standard. Here it is that of a gas
  of constant molecular weight ``M0`` at the kinetic temperature:
  ``a(Z) = a(86 km) sqrt(T(Z) / T(86 km))``, continuous at 86 km. It ignores the fall of
  the true molecular weight (dissociation, diffusive separation), which would raise the
  speed by ``sqrt(M0 / M)``: 1 % at 100 km, 17 % at 200 km. Mach numbers matter only
  where drag does, i.e. low down.
* **Pressure above 86 km** is that of the same model gas, ``P = rho a^2 / gamma``: it keeps
  ``a^2 = gamma P / rho`` true everywhere and is continuous at 86 km, but it is the
  standard's pressure times ``M / M0``: 2 % low at 100 km, 26 % at 200 km, 86 % at
  1000 km. Use it above 86 km for consistency checks only.

The exponential model ``rho = rho0 exp(-h / H)`` takes ``rho0`` and ``H`` from its caller
and has a constant speed of sound, also given by the caller (e.g. US76 sea level,
340.294 m/s). A constant rather than the US76 profile keeps the model defined by its three
arguments alone, so a benchmark can state it completely.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray
from pydantic import BaseModel, ConfigDict, Field, model_validator

from ovtraj.units import M_PER_KM

__all__ = [
    "Atmosphere",
    "ExponentialAtmosphere",
    "TabulatedAtmosphere",
    "US76Atmosphere",
    "US76Table",
]

FloatOrArray = float | NDArray[np.float64]
_Branch = Callable[[NDArray[np.float64]], NDArray[np.float64]]


@runtime_checkable
class Atmosphere(Protocol):
    """What the dynamics need from an atmosphere model."""

    def density(self, altitude_m: ArrayLike) -> FloatOrArray:
        """Mass density [kg/m^3] at geometric altitude ``altitude_m`` [m]."""
        ...

    def speed_of_sound(self, altitude_m: ArrayLike) -> FloatOrArray:
        """Speed of sound [m/s] at geometric altitude ``altitude_m`` [m]."""
        ...


def _increasing(values: list[float], name: str) -> None:
    if np.any(np.diff(values) <= 0.0):
        raise ValueError(f"{name} must be strictly increasing")


class US76Table(BaseModel):
    """The figures of US76 read from ``configs/atmosphere_us76.yaml`` (see its comments)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    gas_constant_J_kmol_K: float = Field(gt=0)
    sea_level_molecular_weight_kg_kmol: float = Field(gt=0)
    geopotential_gravity_m_s2: float = Field(gt=0)
    ratio_of_specific_heats: float = Field(gt=1)
    earth_radius_m: float = Field(gt=0)
    sea_level_temperature_K: float = Field(gt=0)
    sea_level_pressure_Pa: float = Field(gt=0)
    layer_base_geopotential_height_km: list[float] = Field(min_length=1)
    layer_lapse_rate_K_per_km: list[float] = Field(min_length=1)
    lower_region_top_altitude_km: float = Field(gt=0)
    molecular_weight_ratio_altitude_km: list[float] = Field(min_length=2)
    molecular_weight_ratio: list[float] = Field(min_length=2)
    isothermal_top_altitude_km: float
    ellipse_amplitude_K: float
    ellipse_semi_axis_km: float
    ellipse_top_altitude_km: float
    linear_gradient_K_per_km: float
    linear_top_altitude_km: float
    exospheric_temperature_K: float = Field(gt=0)
    exponential_rate_per_km: float = Field(gt=0)
    upper_density_nodes_km_kg_m3: list[tuple[float, float]] = Field(min_length=1)

    @model_validator(mode="after")
    def _check_shapes(self) -> US76Table:
        if len(self.layer_base_geopotential_height_km) != len(self.layer_lapse_rate_K_per_km):
            raise ValueError("one lapse rate per layer base is needed")
        if self.layer_base_geopotential_height_km[0] != 0.0:
            raise ValueError("the first layer must start at sea level")
        _increasing(self.layer_base_geopotential_height_km, "layer_base_geopotential_height_km")
        if len(self.molecular_weight_ratio_altitude_km) != len(self.molecular_weight_ratio):
            raise ValueError("one molecular weight ratio per altitude is needed")
        _increasing(self.molecular_weight_ratio_altitude_km, "molecular_weight_ratio_altitude_km")
        if self.molecular_weight_ratio[0] != 1.0:
            raise ValueError("the molecular weight ratio must start at 1 (sea-level air)")
        segment_tops = [
            self.lower_region_top_altitude_km,
            self.isothermal_top_altitude_km,
            self.ellipse_top_altitude_km,
            self.linear_top_altitude_km,
        ]
        _increasing(segment_tops, "the upper temperature segment altitudes")
        altitudes = [z for z, _ in self.upper_density_nodes_km_kg_m3]
        _increasing([self.lower_region_top_altitude_km, *altitudes], "density node altitudes")
        if any(rho <= 0.0 for _, rho in self.upper_density_nodes_km_kg_m3):
            raise ValueError("density nodes must be positive")
        return self


def _readonly(values: ArrayLike) -> NDArray[np.float64]:
    array = np.array(values, dtype=float)
    array.setflags(write=False)
    return array


def _layer_pressure(
    base_pressure: ArrayLike,
    base_temperature: ArrayLike,
    lapse_rate: ArrayLike,
    height_above_base: ArrayLike,
    hydrostatic_constant: float,
) -> NDArray[np.float64]:
    """Pressure in a layer of linear ``T_M``: US76 eq. (33a), or eq. (33b) where isothermal.

    ``hydrostatic_constant`` is ``g0' M0 / R*`` [K/m'].
    """
    base_pressure = np.asarray(base_pressure, dtype=float)
    base_temperature = np.asarray(base_temperature, dtype=float)
    lapse_rate = np.asarray(lapse_rate, dtype=float)
    height_above_base = np.asarray(height_above_base, dtype=float)
    isothermal = lapse_rate == 0.0
    # Evaluate both branches everywhere without dividing by a zero lapse rate.
    safe_lapse = np.where(isothermal, 1.0, lapse_rate)
    temperature = base_temperature + lapse_rate * height_above_base
    gradient = (base_temperature / temperature) ** (hydrostatic_constant / safe_lapse)
    isothermal_factor = np.exp(-hydrostatic_constant * height_above_base / base_temperature)
    return base_pressure * np.where(isothermal, isothermal_factor, gradient)


class US76Atmosphere:
    """U.S. Standard Atmosphere 1976, 0-1000 km geometric altitude (see the module notes).

    Build it once with :func:`ovtraj.config.physical.us76_atmosphere` (or
    :func:`~ovtraj.config.physical.default_atmosphere`); the tables are
    prepared in the constructor, so calls are cheap. The arrays below are read-only and
    describe the whole model, for code that needs to rebuild it in another form (e.g. a
    symbolic expression for a compiled integrator):

    ``layer_base_geopotential_height_m``, ``layer_lapse_rate_K_per_m``,
    ``layer_base_temperature_K`` (molecular-scale), ``layer_base_pressure_Pa``
        The seven layers below 86 km (US76 Table 4, base values computed).
    ``molecular_weight_ratio_altitude_m``, ``molecular_weight_ratio``
        ``M / M0`` between 80 and 86 km (Table 8), for the kinetic temperature.
    ``node_altitude_m``, ``node_log_density``
        Density nodes from 86 km to the top, ``ln(rho / (kg/m^3))``, 86 km node computed.

    Scalars: ``lower_region_top_altitude_m`` (86 km), ``top_altitude_m`` (1000 km),
    ``temperature_86km_K`` and ``speed_of_sound_86km_m_s`` at the join, and ``table``, the
    :class:`US76Table` it was built from.
    """

    def __init__(self, table: US76Table) -> None:
        self.table = table
        self._gas_constant = table.gas_constant_J_kmol_K
        self._molecular_weight = table.sea_level_molecular_weight_kg_kmol
        self._gamma = table.ratio_of_specific_heats
        self._earth_radius = table.earth_radius_m
        self._hydrostatic_constant = (
            table.geopotential_gravity_m_s2 * self._molecular_weight / self._gas_constant
        )

        base_heights = np.array(table.layer_base_geopotential_height_km) * M_PER_KM
        lapse_rates = np.array(table.layer_lapse_rate_K_per_km) / M_PER_KM
        base_temperatures = [table.sea_level_temperature_K]
        base_pressures = [table.sea_level_pressure_Pa]
        for i in range(len(base_heights) - 1):
            thickness = base_heights[i + 1] - base_heights[i]
            base_temperatures.append(base_temperatures[i] + lapse_rates[i] * thickness)
            base_pressures.append(
                float(
                    _layer_pressure(
                        base_pressures[i],
                        base_temperatures[i],
                        lapse_rates[i],
                        thickness,
                        self._hydrostatic_constant,
                    )
                )
            )
        self.layer_base_geopotential_height_m = _readonly(base_heights)
        self.layer_lapse_rate_K_per_m = _readonly(lapse_rates)
        self.layer_base_temperature_K = _readonly(base_temperatures)
        self.layer_base_pressure_Pa = _readonly(base_pressures)
        self.molecular_weight_ratio_altitude_m = _readonly(
            np.array(table.molecular_weight_ratio_altitude_km) * M_PER_KM
        )
        self.molecular_weight_ratio = _readonly(table.molecular_weight_ratio)

        z7 = table.lower_region_top_altitude_km * M_PER_KM
        self.lower_region_top_altitude_m = z7
        at_z7 = np.array([z7])
        molecular_temperature_z7, pressure_z7 = self._lower_state(at_z7)
        density_z7 = self._lower_density(molecular_temperature_z7, pressure_z7)[0]
        self.temperature_86km_K = float(self._lower_temperature(at_z7, molecular_temperature_z7)[0])
        self.speed_of_sound_86km_m_s = float(
            self._lower_speed_of_sound(molecular_temperature_z7)[0]
        )

        nodes = np.array(table.upper_density_nodes_km_kg_m3)
        self.node_altitude_m = _readonly(np.concatenate(([z7], nodes[:, 0] * M_PER_KM)))
        self.node_log_density = _readonly(np.log(np.concatenate(([density_z7], nodes[:, 1]))))
        self._node_slope = np.diff(self.node_log_density) / np.diff(self.node_altitude_m)
        self.top_altitude_m = float(self.node_altitude_m[-1])

        # Upper temperature segments, each based on the value where the previous one ends.
        self._z8 = table.isothermal_top_altitude_km * M_PER_KM
        self._z9 = table.ellipse_top_altitude_km * M_PER_KM
        self._z10 = table.linear_top_altitude_km * M_PER_KM
        self._ellipse_amplitude = table.ellipse_amplitude_K
        self._ellipse_semi_axis = table.ellipse_semi_axis_km * M_PER_KM
        self._ellipse_centre = self.temperature_86km_K - self._ellipse_amplitude
        self._linear_gradient = table.linear_gradient_K_per_km / M_PER_KM
        self._exospheric_temperature = table.exospheric_temperature_K
        self._exponential_rate = table.exponential_rate_per_km / M_PER_KM
        self._t9 = float(self._ellipse_temperature(np.array([self._z9]))[0])
        self._t10 = self._t9 + self._linear_gradient * (self._z10 - self._z9)

    # -- public quantities ----------------------------------------------------------------

    def density(self, altitude_m: ArrayLike) -> FloatOrArray:
        """Mass density [kg/m^3]: US76 eq. (42) below 86 km, log-linear nodes above."""
        return self._evaluate(
            altitude_m,
            lambda z: self._lower_density(*self._lower_state(z)),
            self._upper_density,
        )

    def temperature(self, altitude_m: ArrayLike) -> FloatOrArray:
        """Kinetic temperature [K]: ``T_M M / M0`` below 86 km, Table 5 closed forms above."""
        return self._evaluate(
            altitude_m,
            lambda z: self._lower_temperature(z, self._lower_state(z)[0]),
            self._upper_temperature,
        )

    def pressure(self, altitude_m: ArrayLike) -> FloatOrArray:
        """Pressure [Pa]: US76 eqs. (33a)/(33b) below 86 km; above, ``rho a^2 / gamma``.

        Above 86 km this is the pressure of the constant-``M0`` model gas (module notes):
        the standard's pressure times ``M / M0``.
        """
        return self._evaluate(
            altitude_m,
            lambda z: self._lower_state(z)[1],
            lambda z: self._upper_density(z) * self._upper_speed_of_sound(z) ** 2 / self._gamma,
        )

    def speed_of_sound(self, altitude_m: ArrayLike) -> FloatOrArray:
        """Speed of sound [m/s]: US76 eq. (50) below 86 km, ``a(86 km) sqrt(T/T(86 km))`` above."""
        return self._evaluate(
            altitude_m,
            lambda z: self._lower_speed_of_sound(self._lower_state(z)[0]),
            self._upper_speed_of_sound,
        )

    # -- internals (arrays of geometric altitude in metres, already range-checked) ----------

    def _evaluate(self, altitude_m: ArrayLike, lower: _Branch, upper: _Branch) -> FloatOrArray:
        z = np.asarray(altitude_m, dtype=float)
        if z.ndim == 0:
            # Integrators call with scalars: skip the masking, same arithmetic.
            value = float(z)
            if not 0.0 <= value <= self.top_altitude_m:
                raise self._range_error(value)
            branch = lower if value < self.lower_region_top_altitude_m else upper
            return float(branch(z.reshape(1))[0])
        inside = (z >= 0.0) & (z <= self.top_altitude_m)
        if not np.all(inside):
            raise self._range_error(z[~inside].flat[0])
        flat = z.ravel()
        out = np.empty_like(flat)
        below = flat < self.lower_region_top_altitude_m
        if np.any(below):
            out[below] = lower(flat[below])
        if not np.all(below):
            out[~below] = upper(flat[~below])
        return out.reshape(z.shape)

    def _range_error(self, offending: float) -> ValueError:
        return ValueError(
            f"altitude_m must lie in [0, {self.top_altitude_m / M_PER_KM:g} km] "
            f"(US76 range, geometric altitude in metres); got {offending!r} m"
        )

    def _lower_state(self, z: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
        """Molecular-scale temperature [K] and pressure [Pa] below 86 km."""
        h = self._earth_radius * z / (self._earth_radius + z)
        layer = np.searchsorted(self.layer_base_geopotential_height_m, h, side="right") - 1
        above_base = h - self.layer_base_geopotential_height_m[layer]
        lapse = self.layer_lapse_rate_K_per_m[layer]
        base_temperature = self.layer_base_temperature_K[layer]
        molecular_temperature = base_temperature + lapse * above_base
        pressure = _layer_pressure(
            self.layer_base_pressure_Pa[layer],
            base_temperature,
            lapse,
            above_base,
            self._hydrostatic_constant,
        )
        return molecular_temperature, pressure

    def _lower_density(self, molecular_temperature: NDArray, pressure: NDArray) -> NDArray:
        return pressure * self._molecular_weight / (self._gas_constant * molecular_temperature)

    def _lower_temperature(self, z: NDArray, molecular_temperature: NDArray) -> NDArray:
        # np.interp holds the first ratio (unity) below 80 km.
        ratio = np.interp(z, self.molecular_weight_ratio_altitude_m, self.molecular_weight_ratio)
        return molecular_temperature * ratio

    def _lower_speed_of_sound(self, molecular_temperature: NDArray) -> NDArray:
        return np.sqrt(
            self._gamma * self._gas_constant * molecular_temperature / self._molecular_weight
        )

    def _upper_density(self, z: NDArray) -> NDArray:
        # z >= the first node; the top altitude belongs to the last interval.
        node = np.minimum(
            np.searchsorted(self.node_altitude_m, z, side="right") - 1, len(self._node_slope) - 1
        )
        log_density = self.node_log_density[node] + self._node_slope[node] * (
            z - self.node_altitude_m[node]
        )
        return np.exp(log_density)

    def _upper_temperature(self, z: NDArray) -> NDArray:
        temperature = np.full_like(z, self.temperature_86km_K)
        ellipse = (z > self._z8) & (z <= self._z9)
        temperature[ellipse] = self._ellipse_temperature(z[ellipse])
        linear = (z > self._z9) & (z <= self._z10)
        temperature[linear] = self._t9 + self._linear_gradient * (z[linear] - self._z9)
        exponential = z > self._z10
        r0, z10 = self._earth_radius, self._z10
        xi = (z[exponential] - z10) * (r0 + z10) / (r0 + z[exponential])
        temperature[exponential] = self._exospheric_temperature - (
            self._exospheric_temperature - self._t10
        ) * np.exp(-self._exponential_rate * xi)
        return temperature

    def _ellipse_temperature(self, z: NDArray) -> NDArray:
        x = (z - self._z8) / self._ellipse_semi_axis
        return self._ellipse_centre + self._ellipse_amplitude * np.sqrt(1.0 - x**2)

    def _upper_speed_of_sound(self, z: NDArray) -> NDArray:
        return self.speed_of_sound_86km_m_s * np.sqrt(
            self._upper_temperature(z) / self.temperature_86km_K
        )


class ExponentialAtmosphere:
    """Pure exponential density ``rho = rho0 exp(-h / H)`` with a constant speed of sound.

    Parameters
    ----------
    rho0_kg_m3
        Density at zero altitude [kg/m^3].
    scale_height_m
        Scale height ``H`` [m].
    speed_of_sound_m_s
        Speed of sound [m/s], the same at every altitude (see the module notes).

    Defined for every altitude: no range is imposed.
    """

    def __init__(self, rho0_kg_m3: float, scale_height_m: float, speed_of_sound_m_s: float) -> None:
        for name, value in (
            ("rho0_kg_m3", rho0_kg_m3),
            ("scale_height_m", scale_height_m),
            ("speed_of_sound_m_s", speed_of_sound_m_s),
        ):
            if not (np.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be positive and finite, got {value!r}")
        self.rho0_kg_m3 = float(rho0_kg_m3)
        self.scale_height_m = float(scale_height_m)
        self.speed_of_sound_m_s = float(speed_of_sound_m_s)

    def __repr__(self) -> str:
        return (
            f"ExponentialAtmosphere(rho0_kg_m3={self.rho0_kg_m3!r}, "
            f"scale_height_m={self.scale_height_m!r}, "
            f"speed_of_sound_m_s={self.speed_of_sound_m_s!r})"
        )

    def density(self, altitude_m: ArrayLike) -> FloatOrArray:
        """Density [kg/m^3] at altitude ``altitude_m`` [m]."""
        z = np.asarray(altitude_m, dtype=float)
        rho = self.rho0_kg_m3 * np.exp(-z / self.scale_height_m)
        return float(rho) if z.ndim == 0 else rho

    def speed_of_sound(self, altitude_m: ArrayLike) -> FloatOrArray:
        """Speed of sound [m/s]: the constant given at construction, shaped like the input."""
        z = np.asarray(altitude_m, dtype=float)
        return self.speed_of_sound_m_s if z.ndim == 0 else np.full(z.shape, self.speed_of_sound_m_s)


class TabulatedAtmosphere:
    """An atmosphere sampled on a uniform altitude grid, for vectorised integrators.

    ``ln rho`` and ``ln p`` are interpolated linearly (exact for exponential layers)
    and the speed of sound linearly, between nodes every ``step_m`` from 0 to
    ``top_m``. Altitudes outside the grid are clamped to it (a trajectory that
    leaves it is flagged by its caller, not here), so the lookup never raises
    inside a batch. :meth:`lookup` costs a few array operations whatever the
    model behind it; ``tests/test_launch_dynamics.py`` bounds its error against the
    model it samples (1e-4, 1e-3 in the cells holding a US76 layer base).

    Parameters
    ----------
    atmosphere
        A model with ``density``, ``pressure`` and ``speed_of_sound`` [SI] of
        geometric altitude [m], e.g. :class:`US76Atmosphere`.
    top_m, step_m
        Grid top and spacing [m].
    """

    def __init__(self, atmosphere: US76Atmosphere, *, top_m: float, step_m: float) -> None:
        if not (step_m > 0 and top_m > step_m):
            raise ValueError(f"need 0 < step_m < top_m, got step_m={step_m!r}, top_m={top_m!r}")
        nodes = np.arange(0.0, top_m + 0.5 * step_m, step_m)
        self.step_m = float(step_m)
        self.top_m = float(nodes[-1])
        self._last = len(nodes) - 2
        self._log_density = np.log(atmosphere.density(nodes))
        self._log_pressure = np.log(atmosphere.pressure(nodes))
        self._sound = np.asarray(atmosphere.speed_of_sound(nodes), dtype=float)
        self._d_log_density = np.diff(self._log_density)
        self._d_log_pressure = np.diff(self._log_pressure)
        self._d_sound = np.diff(self._sound)

    def lookup(self, altitude_m: NDArray[np.float64]) -> tuple[NDArray, NDArray, NDArray]:
        """Density [kg/m^3], pressure [Pa] and speed of sound [m/s] at ``altitude_m`` [m]."""
        # fmax/fmin map NaN to the bound: a diverging row never breaks the lookup.
        x = np.fmin(np.fmax(altitude_m, 0.0), self.top_m) / self.step_m
        k = np.minimum(x.astype(np.intp), self._last)
        f = x - k
        rho = np.exp(self._log_density[k] + f * self._d_log_density[k])
        p = np.exp(self._log_pressure[k] + f * self._d_log_pressure[k])
        a = self._sound[k] + f * self._d_sound[k]
        return rho, p, a
