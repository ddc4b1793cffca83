"""Atmosphere models against the published U.S. Standard Atmosphere 1976 tables.

References are typed from NOAA-S/T 76-1562, "U.S. Standard Atmosphere, 1976": Table I
(geometric altitude, SI units) and Table 4 (layer bases). They are independent of the
model's configuration: above 86 km the density checks sit between the model's nodes.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from ovtraj.astro.atmosphere import Atmosphere, ExponentialAtmosphere, US76Atmosphere
from ovtraj.config.physical import default_atmosphere, us76_atmosphere
from ovtraj.paths import config_path

KM = 1000.0
# US76 constants, used only to place the references (Table 4 bases are geopotential).
R0_US76_M = 6356766.0
GAMMA_US76 = 1.4

# Density [kg/m^3], Table I, 0-86 km; the model is the standard's closed form here.
DENSITY_BELOW_86_KM = {
    0: 1.2250,
    1: 1.1117,
    5: 7.3643e-1,
    10: 4.1351e-1,
    11: 3.6480e-1,
    15: 1.9476e-1,
    20: 8.8910e-2,
    25: 4.0084e-2,
    30: 1.8410e-2,
    32: 1.3555e-2,
    40: 3.9957e-3,
    50: 1.0269e-3,
    60: 3.0968e-4,
    70: 8.2829e-5,
    75: 3.9921e-5,
    80: 1.8458e-5,
    85: 8.2196e-6,
    86: 6.958e-6,
}

# Density [kg/m^3] above 86 km at altitudes that are not density nodes of the model.
# Table I density entries:
DENSITY_ABOVE_86_KM_TABLE = {
    115: 4.289e-8,
    140: 3.831e-9,
    150: 2.076e-9,
    175: 6.339e-10,
    180: 5.194e-10,
    190: 3.581e-10,
    350: 7.014e-12,
    450: 1.184e-12,
    750: 1.788e-14,
    985: 3.797e-15,
}
# rho = P M / (R* T) from Table I's pressure, mean molecular weight and kinetic temperature
# at the same altitude, rounded to Table I's four figures:
DENSITY_ABOVE_86_KM_FROM_P_M_T = {
    88: 4.875e-6,
    93: 1.999e-6,
    97: 9.685e-7,
    103: 3.299e-7,
    107: 1.642e-7,
    111: 8.111e-8,
    113: 5.811e-8,
    117: 3.246e-8,
    119: 2.509e-8,
    125: 1.291e-8,
    135: 5.466e-9,
    170: 7.815e-10,
    210: 1.846e-10,
    220: 1.367e-10,
    230: 1.029e-10,
    270: 3.738e-11,
    330: 1.035e-11,
    370: 4.820e-12,
    410: 2.350e-12,
    490: 6.128e-13,
    550: 2.384e-13,
    650: 5.713e-14,
    850: 7.825e-15,
    950: 4.451e-15,
    975: 3.967e-15,
}

# Kinetic temperature [K] and speed of sound [m/s], Table I.
TEMPERATURE_SOUND_BELOW_86_KM = {
    0: (288.150, 340.294),
    5: (255.676, 320.55),
    11: (216.774, 295.154),
    20: (216.650, 295.070),
    25: (221.552, 298.39),
    40: (250.350, 317.19),
    50: (270.650, 329.799),
    60: (247.021, 315.07),
    75: (208.399, 289.40),
}
TEMPERATURE_ABOVE_86_KM = {
    86: 186.87,
    90: 186.87,
    100: 195.08,
    110: 240.00,
    115: 300.00,
    120: 360.00,
    150: 634.39,
    200: 854.56,
    300: 976.01,
    500: 999.24,
    750: 999.99,
    1000: 1000.00,
}
# M / M0 against geometric altitude, Table 8 (unity below 80 km).
MOLECULAR_WEIGHT_RATIO = {
    79.0: 1.0,
    80.5: 0.999996,
    81.0: 0.999989,
    81.5: 0.999971,
    82.0: 0.999941,
    82.5: 0.999909,
    83.0: 0.999870,
    83.5: 0.999829,
    84.0: 0.999786,
    84.5: 0.999741,
    85.0: 0.999694,
    85.5: 0.999641,
    86.0: 0.999579,
}
SPEED_OF_SOUND_85_KM = 275.52  # Table I
SPEED_OF_SOUND_86_KM = 274.10  # Table I

# Pressure [Pa] at the layer bases, Table 4 (geopotential height km'), and Table I.
PRESSURE_LAYER_BASES = {
    11: 22632.06,
    20: 5474.889,
    32: 868.0187,
    47: 110.9063,
    51: 66.93887,
    71: 3.956420,
}
PRESSURE_GEOMETRIC = {
    5: 5.4048e4,
    15: 1.2111e4,
    25: 2.5492e3,
    40: 2.8714e2,
    50: 7.9779e1,
    60: 2.1958e1,
    75: 2.3881,
    85: 4.4568e-1,
    86: 3.7338e-1,
}

# Table I pressure [Pa] and mean molecular weight [kg/kmol] above 86 km, for the documented
# behaviour of the model-gas pressure there (P_model / P_US76 = M / M0).
PRESSURE_AND_MOLECULAR_WEIGHT_ABOVE_86_KM = {
    100: (3.2011e-2, 28.40),
    200: (8.4736e-5, 21.30),
    500: (3.0236e-7, 14.33),
    1000: (7.5138e-9, 3.94),
}
M0_US76 = 28.9644

# Below 86 km the model is the standard's closed form, so only the tables' rounding remains.
EXACT_REL = 2e-4


def assert_rel(actual: float, expected: float, rel: float) -> None:
    # Not pytest.approx: its default absolute tolerance (1e-12) would swallow densities.
    assert abs(actual / expected - 1.0) <= rel, f"{actual!r} vs {expected!r}"


def geometric_from_geopotential(h_m: float) -> float:
    return R0_US76_M * h_m / (R0_US76_M - h_m)


@pytest.fixture(scope="module")
def atm() -> US76Atmosphere:
    return default_atmosphere()


# -- US76 against the tables ----------------------------------------------------------------


@pytest.mark.parametrize(("z_km", "rho"), DENSITY_BELOW_86_KM.items())
def test_density_below_86_km(atm, z_km, rho):
    assert_rel(atm.density(z_km * KM), rho, EXACT_REL)


@pytest.mark.parametrize(
    ("z_km", "rho"),
    list(DENSITY_ABOVE_86_KM_TABLE.items()) + list(DENSITY_ABOVE_86_KM_FROM_P_M_T.items()),
)
def test_density_above_86_km_between_nodes(atm, z_km, rho):
    assert not np.any(np.isclose(atm.node_altitude_m, z_km * KM)), "reference is a node"
    assert_rel(atm.density(z_km * KM), rho, 0.01)


@pytest.mark.parametrize(("z_km", "t_a"), TEMPERATURE_SOUND_BELOW_86_KM.items())
def test_temperature_and_speed_of_sound_below_86_km(atm, z_km, t_a):
    temperature, sound = t_a
    assert_rel(atm.temperature(z_km * KM), temperature, EXACT_REL)
    assert_rel(atm.speed_of_sound(z_km * KM), sound, EXACT_REL)


def test_speed_of_sound_near_86_km(atm):
    assert_rel(atm.speed_of_sound(85 * KM), SPEED_OF_SOUND_85_KM, EXACT_REL)
    assert_rel(atm.speed_of_sound(86 * KM), SPEED_OF_SOUND_86_KM, EXACT_REL)


@pytest.mark.parametrize(("z_km", "ratio"), MOLECULAR_WEIGHT_RATIO.items())
def test_kinetic_temperature_80_to_86_km(atm, z_km, ratio):
    # T = T_M M / M0, with T_M from the last layer of Table 4 (214.65 K at 71 km', -2 K/km').
    h_km = R0_US76_M * z_km / (R0_US76_M + z_km * KM)
    molecular_temperature = 214.65 - 2.0 * (h_km - 71.0)
    assert_rel(atm.temperature(z_km * KM), molecular_temperature * ratio, 1e-9)


@pytest.mark.parametrize(("z_km", "temperature"), TEMPERATURE_ABOVE_86_KM.items())
def test_kinetic_temperature_above_86_km(atm, z_km, temperature):
    assert_rel(atm.temperature(z_km * KM), temperature, 1e-3)


def test_speed_of_sound_above_86_km_follows_kinetic_temperature(atm):
    # Documented approximation: a gas of constant M0 at the standard's kinetic temperature.
    t86 = TEMPERATURE_ABOVE_86_KM[86]
    for z_km in (100, 120, 300, 1000):
        expected = SPEED_OF_SOUND_86_KM * math.sqrt(TEMPERATURE_ABOVE_86_KM[z_km] / t86)
        assert_rel(atm.speed_of_sound(z_km * KM), expected, 1e-3)


@pytest.mark.parametrize(("h_km", "pressure"), PRESSURE_LAYER_BASES.items())
def test_pressure_at_layer_bases(atm, h_km, pressure):
    z = geometric_from_geopotential(h_km * KM)
    assert_rel(atm.pressure(z), pressure, EXACT_REL)


@pytest.mark.parametrize(("z_km", "pressure"), PRESSURE_GEOMETRIC.items())
def test_pressure_geometric(atm, z_km, pressure):
    assert_rel(atm.pressure(z_km * KM), pressure, EXACT_REL)


def test_pressure_density_speed_of_sound_consistent(atm):
    z = np.linspace(0.0, 1000 * KM, 2001)
    expected = atm.density(z) * atm.speed_of_sound(z) ** 2 / GAMMA_US76
    assert np.allclose(atm.pressure(z), expected, rtol=1e-12, atol=0.0)


@pytest.mark.parametrize(("z_km", "p_m"), PRESSURE_AND_MOLECULAR_WEIGHT_ABOVE_86_KM.items())
def test_pressure_above_86_km_is_model_gas_pressure(atm, z_km, p_m):
    pressure, molecular_weight = p_m
    ratio = atm.pressure(z_km * KM) / pressure
    assert_rel(ratio, molecular_weight / M0_US76, 0.01)


# -- continuity and shape -------------------------------------------------------------------


def _boundaries(atm: US76Atmosphere) -> list[float]:
    table = atm.table
    layer_bases = [geometric_from_geopotential(h) for h in atm.layer_base_geopotential_height_m]
    segment_tops = [
        table.isothermal_top_altitude_km * KM,
        table.ellipse_top_altitude_km * KM,
        table.linear_top_altitude_km * KM,
    ]
    below_top = [z for z in atm.node_altitude_m if z < atm.top_altitude_m]
    return layer_bases[1:] + list(atm.molecular_weight_ratio_altitude_m) + segment_tops + below_top


@pytest.mark.parametrize("quantity", ["density", "temperature", "speed_of_sound", "pressure"])
def test_continuous_at_every_boundary(atm, quantity):
    boundaries = np.array(_boundaries(atm))
    assert len(boundaries) > 80
    f = getattr(atm, quantity)
    below, above = f(boundaries - 1e-6), f(boundaries + 1e-6)
    jump = np.abs(above / below - 1.0)
    worst = int(np.argmax(jump))
    assert jump[worst] < 1e-9, f"{quantity} jumps by {jump[worst]:.2e} at {boundaries[worst]} m"


def test_density_strictly_decreasing(atm):
    rho = atm.density(np.linspace(0.0, 1000 * KM, 200_001))
    assert np.all(np.diff(rho) < 0.0)


def test_86_km_node_is_lower_model_value(atm):
    assert atm.node_altitude_m[0] == 86 * KM
    assert_rel(math.exp(atm.node_log_density[0]), atm.density(86 * KM - 1e-9), 1e-9)


def test_vectorised_equals_scalar(atm):
    z = np.array([[0.0, 10.5e3, 47.3e3], [85.9e3, 86e3, 86.1e3], [111.1e3, 500e3, 1e6]])
    for quantity in ("density", "temperature", "pressure", "speed_of_sound"):
        f = getattr(atm, quantity)
        values = f(z)
        assert values.shape == z.shape
        scalars = np.array([[f(float(v)) for v in row] for row in z])
        assert np.array_equal(values, scalars)
        assert isinstance(f(1234.0), float)
        assert isinstance(f(np.float64(1234.0)), float)
    assert atm.density([1e3, 2e3]).shape == (2,)


def test_tables_are_exposed_read_only(atm):
    assert atm.layer_base_pressure_Pa[0] == 101325.0
    assert len(atm.node_altitude_m) == len(atm.node_log_density)
    with pytest.raises(ValueError):
        atm.node_log_density[0] = 0.0


@pytest.mark.parametrize(
    "bad", [-1.0, -1e-9, 1000 * KM + 1e-6, 2e6, math.nan, [0.0, 5e3, -3.0], [1e3, 1.1e6]]
)
@pytest.mark.parametrize("quantity", ["density", "temperature", "pressure", "speed_of_sound"])
def test_out_of_range_raises(atm, quantity, bad):
    with pytest.raises(ValueError, match=r"altitude_m.*\[0, 1000 km\]"):
        getattr(atm, quantity)(bad)


# -- construction ---------------------------------------------------------------------------


def test_from_config_default_and_explicit_path_agree():
    implicit = us76_atmosphere()
    explicit = us76_atmosphere(config_path("atmosphere_us76.yaml"))
    z = np.linspace(0.0, 1000 * KM, 101)
    assert np.array_equal(implicit.density(z), explicit.density(z))
    assert default_atmosphere() is default_atmosphere()


def test_config_rejects_unordered_nodes(tmp_path: Path):
    with open(config_path("atmosphere_us76.yaml"), encoding="utf-8") as fh:
        data = yaml.safe_load(fh)
    nodes = data["upper_density_nodes_km_kg_m3"]
    nodes[3], nodes[4] = nodes[4], nodes[3]
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    with pytest.raises(ValueError, match="increasing"):
        us76_atmosphere(path)


# -- exponential model ----------------------------------------------------------------------


def test_exponential_closed_form():
    model = ExponentialAtmosphere(rho0_kg_m3=1.225, scale_height_m=7200.0, speed_of_sound_m_s=340.0)
    for h in (0.0, 7200.0, 50e3, 120e3):
        assert_rel(model.density(h), 1.225 * math.exp(-h / 7200.0), 1e-14)
        assert model.speed_of_sound(h) == 340.0
    assert_rel(model.density(7200.0), 1.225 / math.e, 1e-14)


def test_exponential_vectorised_equals_scalar():
    model = ExponentialAtmosphere(rho0_kg_m3=2.0, scale_height_m=8000.0, speed_of_sound_m_s=300.0)
    h = np.array([[0.0, 1e3], [60e3, 400e3]])
    rho = model.density(h)
    assert rho.shape == h.shape
    assert np.array_equal(rho, np.array([[model.density(float(v)) for v in row] for row in h]))
    assert np.array_equal(model.speed_of_sound(h), np.full(h.shape, 300.0))
    assert isinstance(model.density(1.0), float)
    assert isinstance(model.speed_of_sound(1.0), float)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"rho0_kg_m3": 0.0, "scale_height_m": 7e3, "speed_of_sound_m_s": 340.0},
        {"rho0_kg_m3": 1.2, "scale_height_m": -7e3, "speed_of_sound_m_s": 340.0},
        {"rho0_kg_m3": 1.2, "scale_height_m": 7e3, "speed_of_sound_m_s": math.nan},
    ],
)
def test_exponential_rejects_bad_parameters(kwargs):
    with pytest.raises(ValueError):
        ExponentialAtmosphere(**kwargs)


def test_both_models_satisfy_protocol(atm):
    assert isinstance(atm, Atmosphere)
    assert isinstance(ExponentialAtmosphere(1.2, 7e3, 340.0), Atmosphere)
