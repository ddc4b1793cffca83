"""US76 mass density from 86 to 1000 km: the density nodes of ``configs/atmosphere_us76.yaml``.

Provenance of the config's ``upper_density_nodes_km_kg_m3``. Seventeen nodes are the
published density figures of Table I (geometric altitude, SI) of the U.S. Standard
Atmosphere, 1976 (NOAA-S/T 76-1562, "US76"); they are copied into :data:`TABLE_I_DENSITY`
and marked ``# Table I entry`` in the config. The others are computed here: this script
integrates the standard's number-density equations for N2, O, O2, Ar, He and H above 86 km,
forms the mass density and rounds it to Table I's four significant figures.

Usage (from the repository root)::

    python tools/us76_upper_atmosphere.py           # print the node list in the config's format
    python tools/us76_upper_atmosphere.py --check   # compare with configs/atmosphere_us76.yaml

``--check`` exits with status 1 if the config's altitudes or published entries differ from
this script's, if a computed node differs from the integration beyond its fourth significant
figure, or if a published entry differs from the integration by more than 0.15 %.

What is computed
----------------
Geometric altitude ``Z``, SI units, kmol-based molar quantities as in the standard.

* Kinetic temperature ``T(Z)`` and ``dT/dZ``: the closed forms of Table 5 (isothermal at
  ``T7`` to 91 km, ellipse to 110 km, +12 K/km to 120 km, then
  ``T = T_inf - (T_inf - T10) exp(-lambda xi)``, ``xi = (Z - Z10)(r0 + Z10)/(r0 + Z)``).
  The segment figures (``T7 = 186.8673 K``, ``Tc``, ``A``, ``a``, ``T9 = 240 K``,
  ``T10 = 360 K``, ``T_inf = 1000 K``, ``lambda``) are those of the config.
* Gravity ``g = g0 (r0 / (r0 + Z))^2``.
* N2, in mixing equilibrium below 100 km and diffusive equilibrium above::

      n_N2(Z) = n_N2(86 km) (T7 / T) exp(-int_86^Z M g / (R* T) dZ),
      M = M0 for Z < 100 km, M(N2) from 100 km.

* O, O2, Ar, He (molecular and eddy diffusion with a vertical-flux term)::

      n_i(Z) = n_i(86 km) (T7 / T) exp(-int_86^Z (f_i + v_i / (D_i + K)) dZ),
      f_i = g / (R* T) D_i / (D_i + K) (M_i + M K / D_i + alpha_i R* (dT/dZ) / g),
      D_i = a_i / n_bg (T / 273.15 K)^b_i,
      v_i / (D_i + K) = Q_i (Z - U_i)^2 exp(-W_i (Z - U_i)^3)
                        + q_i (u_i - Z)^2 exp(-w_i (u_i - Z)^3)   [q term: O below 97 km].

  ``n_bg`` is ``n_N2`` for O and O2 and ``n_N2 + n_O + n_O2`` for Ar and He. ``K`` is the
  eddy-diffusion coefficient: 120 m^2/s below 95 km,
  ``120 exp(1 - 400 / (400 - (Z - 95)^2))`` (``Z`` in km) from 95 to 115 km, zero above.
  ``M`` is ``M0`` below 100 km; from 100 km it is ``M(N2)`` for O and O2 and the mean
  molecular weight of the N2-O-O2 mixture for Ar and He, as in independent
  implementations of the standard (S. Pietrobon's ``ussa1976``, distributed with PDAS;
  ``cl-ussa1976``).
* H, from 150 km (zero below), with the escape flux ``phi`` below ``Z11 = 500 km`` and in
  diffusive equilibrium above::

      n_H(Z) = [n_H(Z11) + int_Z^Z11 (phi / D_H) (T / T11)^(1 + alpha_H) exp(tau) dZ']
               (T11 / T)^(1 + alpha_H) exp(-tau(Z)),
      tau(Z) = int_Z11^Z M_H g / (R* T) dZ,   T11 = T(Z11),

  the flux integral being dropped above ``Z11``; ``D_H`` uses ``n_bg = n_N2 + n_O + n_O2 +
  n_Ar + n_He``.
* Mass density ``rho = sum_i n_i M_i / N_A``.

Sources of the constants. The physical constants, the molecular weights, the kinetic
temperature figures (Table 5) and the published densities (Table I) are the standard's, as
the project's config and ``ovtraj.astro.atmosphere`` already use them. The coefficients
``a_i``, ``b_i``, ``alpha_i`` are from its Table 6 and ``Q_i, U_i, W_i, q_i, u_i, w_i`` from
its Table 7 (table numbers from memory). The 86 km number densities, ``n_H(500 km)``,
``phi`` and the eddy-diffusion profile are the standard's figures too (from memory; where
each appears in the document is not recorded here). Equation numbers are deliberately not
quoted, as they were not checked against the document: every equation is written out above.

Numerical method
----------------
One grid of exact multiples of the step: 1 m from 86 to 150 km (the eddy-diffusion and flux
terms vary fastest there) and 10 m from 150 to 1000 km; every node altitude is a grid point.
Every integral is a cumulative trapezoid rule (``scipy.integrate.cumulative_trapezoid``) on
that grid; N2 first, then O and O2, then Ar and He (whose background needs O and O2), then
H. Temperature segments are closed at their base (the grid point at 110 km is on the linear
segment, at exactly 240 K); the mean molecular weight ``M`` jumps at 100 km and the grid
point there takes the upper value, ``M(N2)``. That jump makes the rule first-order: halving
both steps moves the nodes by at most 1.3e-6 relative. The integration takes about 0.1 s.

The config's figures are this grid's results rounded to four figures. A few lie within
1e-6 of a rounding boundary (112 km is 6.83751e-08), so another grid can round them the
other way (half the steps gives 6.837e-08 at 112 km): ``--check`` uses this grid.

Known differences from the standard's tables
--------------------------------------------
* Against published Table I densities (the 17 marked nodes, Table I densities at 10 other
  altitudes and ``rho = P M / (R* T)`` from Table I's columns at 25 more, 88-985 km) the
  integration agrees within 0.03 % at every altitude; the marked nodes agree within
  0.029 %, well inside the 0.15 % tolerance of ``--check`` for them.
* An earlier version of these figures used ``M(N2)`` for Ar and He too; that ran 0.06-0.08 %
  low at 800-1000 km, where helium carries most of the mass, and set 18 nodes one unit of
  the fourth figure lower.
* The remaining differences, a few 0.01 % at most, are of the size of Table I's rounding
  to four figures.
* Hydrogen is about 2 % of the mass at 1000 km, where it is in diffusive equilibrium; its
  escape-flux term acts below 500 km, where hydrogen is under 3e-4 of the mass, and changes
  the density by less than 1e-6 relative.
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import cumulative_trapezoid

FloatArray = NDArray[np.float64]

REPO_ROOT = Path(__file__).resolve().parents[1]
DEFAULT_CONFIG = REPO_ROOT / "configs" / "atmosphere_us76.yaml"

KM = 1000.0  # m

# -- Constants of the standard (as in configs/atmosphere_us76.yaml) --------------------------
GAS_CONSTANT = 8314.32  # R* [J/(kmol K)]
AVOGADRO = 6.022169e26  # N_A [1/kmol]
SEA_LEVEL_GRAVITY = 9.80665  # g0 [m/s^2]
EARTH_RADIUS = 6356766.0  # r0 [m]
SEA_LEVEL_MOLECULAR_WEIGHT = 28.9644  # M0 [kg/kmol]

SPECIES = ("N2", "O", "O2", "Ar", "He", "H")
MOLECULAR_WEIGHT = {  # M_i [kg/kmol]; O and H are half of O2 and H2
    "N2": 28.0134,
    "O": 15.9994,
    "O2": 31.9988,
    "Ar": 39.948,
    "He": 4.0026,
    "H": 1.00797,
}

# -- Kinetic temperature above 86 km, Table 5 ------------------------------------------------
Z7 = 86.0 * KM  # bottom of the integration
T7 = 186.8673  # K, isothermal 86-91 km
Z8 = 91.0 * KM
ELLIPSE_CENTRE_TEMPERATURE = 263.1905  # Tc [K]
ELLIPSE_AMPLITUDE = -76.3232  # A [K]
ELLIPSE_SEMI_AXIS = -19.9429 * KM  # a [m]
Z9 = 110.0 * KM
T9 = 240.0  # K
LINEAR_GRADIENT = 12.0 / KM  # L_K,9 [K/m]
Z10 = 120.0 * KM
T10 = 360.0  # K
EXOSPHERIC_TEMPERATURE = 1000.0  # T_inf [K]
EXPONENTIAL_RATE = 0.01875 / KM  # lambda [1/m]
Z12 = 1000.0 * KM  # top of the standard

# -- Composition above 86 km (standard's text and Tables 6 and 7, numbering from memory) ----
MIXING_TOP = 100.0 * KM  # M = M0 below, M(N2) from here
NUMBER_DENSITY_86KM = {  # n_i(Z7) [1/m^3]
    "N2": 1.129794e20,
    "O": 8.6e16,
    "O2": 3.030898e19,
    "Ar": 1.3514e18,
    "He": 7.5817e14,
}
# D_i = a_i / n_bg (T / 273.15 K)^b_i: a_i [1/(m s)], b_i; thermal-diffusion factors alpha_i.
DIFFUSION_A = {"O": 6.986e20, "O2": 4.863e20, "Ar": 4.487e20, "He": 1.7e21, "H": 3.305e21}
DIFFUSION_B = {"O": 0.75, "O2": 0.75, "Ar": 0.87, "He": 0.691, "H": 0.5}
THERMAL_DIFFUSION = {"O": 0.0, "O2": 0.0, "Ar": 0.0, "He": -0.40, "H": -0.25}
DIFFUSION_REFERENCE_TEMPERATURE = 273.15  # K
# Flux term v_i / (D_i + K) = Q (Z - U)^2 exp(-W (Z - U)^3): (Q [1/m^3], U [m], W [1/m^3]).
FLUX_TERM = {
    "O": (-5.809644e-13, 56.90311 * KM, 2.706240e-14),
    "O2": (1.366212e-13, 86.0 * KM, 8.333333e-14),
    "Ar": (9.434079e-14, 86.0 * KM, 8.333333e-14),
    "He": (-2.457369e-13, 86.0 * KM, 6.666667e-13),
}
# Extra term for O only, below u: q (u - Z)^2 exp(-w (u - Z)^3): (q [1/m^3], u [m], w [1/m^3]).
OXYGEN_LOW_FLUX_TERM = (-3.416248e-12, 97.0 * KM, 5.008765e-13)
EDDY_DIFFUSION_86KM = 120.0  # K_7 [m^2/s], up to EDDY_DECAY_BASE
EDDY_DECAY_BASE = 95.0 * KM
EDDY_DECAY_SCALE = 400.0 * KM**2  # the "400" [km^2] of K(Z)
EDDY_TOP = 115.0 * KM  # K = 0 from here
HYDROGEN_BASE = 150.0 * KM  # n_H = 0 below
Z11 = 500.0 * KM
HYDROGEN_500KM = 8.0e10  # n_H(Z11) [1/m^3]
HYDROGEN_FLUX = 7.2e11  # phi [1/(m^2 s)]

# -- Integration grid ------------------------------------------------------------------------
FINE_STEP = 1.0  # m, from Z7 to HYDROGEN_BASE
COARSE_STEP = 10.0  # m, from HYDROGEN_BASE to Z12

# -- Density nodes of the config -------------------------------------------------------------
# (first, last, spacing) in km; "keeps the interpolation within 0.5 % of the standard".
NODE_SPACING_KM = (
    (90.0, 110.0, 5.0),
    (112.0, 130.0, 2.0),
    (133.0, 160.0, 3.0),
    (168.0, 200.0, 8.0),
    (212.5, 300.0, 12.5),
    (320.0, 1000.0, 20.0),
)
# Published densities [kg/m^3] used as they are, Table I (geometric altitude, SI).
TABLE_I_DENSITY = {
    90.0: 3.416e-06,
    95.0: 1.393e-06,
    100.0: 5.604e-07,
    110.0: 9.708e-08,
    120.0: 2.222e-08,
    130.0: 8.152e-09,
    160.0: 1.233e-09,
    200.0: 2.541e-10,
    250.0: 6.073e-11,
    300.0: 1.916e-11,
    400.0: 2.803e-12,
    500.0: 5.215e-13,
    600.0: 1.137e-13,
    700.0: 3.070e-14,
    800.0: 1.136e-14,
    900.0: 5.759e-15,
    1000.0: 3.561e-15,
}
TABLE_I_TOLERANCE = 1.5e-3  # relative, integration vs published entries
TABLE_I_MARK = "# Table I entry"
COMMENT_COLUMN = 26  # where the config's node comments start
SIGNIFICANT_FIGURES = 4


class Node(NamedTuple):
    """A density node: geometric altitude [km], density [kg/m^3], published in Table I?"""

    altitude_km: float
    density_kg_m3: float
    table_i: bool


# -- The standard's profiles -----------------------------------------------------------------


def kinetic_temperature(z: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Kinetic temperature [K] and its gradient [K/m] at geometric altitudes ``z`` [m] >= 86 km."""
    temperature = np.full_like(z, T7)
    gradient = np.zeros_like(z)

    ellipse = (z >= Z8) & (z < Z9)
    x = (z[ellipse] - Z8) / ELLIPSE_SEMI_AXIS
    root = np.sqrt(1.0 - x**2)
    temperature[ellipse] = ELLIPSE_CENTRE_TEMPERATURE + ELLIPSE_AMPLITUDE * root
    gradient[ellipse] = -ELLIPSE_AMPLITUDE * x / (ELLIPSE_SEMI_AXIS * root)

    linear = (z >= Z9) & (z < Z10)
    temperature[linear] = T9 + LINEAR_GRADIENT * (z[linear] - Z9)
    gradient[linear] = LINEAR_GRADIENT

    upper = z >= Z10
    stretch = (EARTH_RADIUS + Z10) / (EARTH_RADIUS + z[upper])
    decay = (EXOSPHERIC_TEMPERATURE - T10) * np.exp(-EXPONENTIAL_RATE * (z[upper] - Z10) * stretch)
    temperature[upper] = EXOSPHERIC_TEMPERATURE - decay
    gradient[upper] = EXPONENTIAL_RATE * stretch**2 * decay
    return temperature, gradient


def gravity(z: FloatArray) -> FloatArray:
    """Acceleration of gravity [m/s^2] at geometric altitudes ``z`` [m]."""
    return SEA_LEVEL_GRAVITY * (EARTH_RADIUS / (EARTH_RADIUS + z)) ** 2


def eddy_diffusion(z: FloatArray) -> FloatArray:
    """Eddy-diffusion coefficient K [m^2/s] at geometric altitudes ``z`` [m]."""
    k = np.where(z < EDDY_DECAY_BASE, EDDY_DIFFUSION_86KM, 0.0)
    decaying = (z >= EDDY_DECAY_BASE) & (z < EDDY_TOP)
    offset2 = (z[decaying] - EDDY_DECAY_BASE) ** 2
    k[decaying] = EDDY_DIFFUSION_86KM * np.exp(
        1.0 - EDDY_DECAY_SCALE / (EDDY_DECAY_SCALE - offset2)
    )
    return k


def molecular_diffusion(
    species: str, background: FloatArray, temperature: FloatArray
) -> FloatArray:
    """Molecular-diffusion coefficient D_i [m^2/s] of ``species`` through ``background`` [1/m^3]."""
    return (
        DIFFUSION_A[species]
        / background
        * (temperature / DIFFUSION_REFERENCE_TEMPERATURE) ** DIFFUSION_B[species]
    )


def flux_term(species: str, z: FloatArray) -> FloatArray:
    """Vertical-flux term v_i / (D_i + K) [1/m] of O, O2, Ar or He at altitudes ``z`` [m]."""
    q, u, w = FLUX_TERM[species]
    term = q * (z - u) ** 2 * np.exp(-w * (z - u) ** 3)
    if species == "O":
        q_low, u_low, w_low = OXYGEN_LOW_FLUX_TERM
        below = z < u_low
        depth = u_low - z[below]
        term[below] += q_low * depth**2 * np.exp(-w_low * depth**3)
    return term


# -- Integration -----------------------------------------------------------------------------


def altitude_grid(fine_step: float = FINE_STEP, coarse_step: float = COARSE_STEP) -> FloatArray:
    """Integration grid [m]: 86-150 km by ``fine_step``, 150-1000 km by ``coarse_step``."""
    parts = []
    for bottom, top, step, closed in (
        (Z7, HYDROGEN_BASE, fine_step, False),
        (HYDROGEN_BASE, Z12, coarse_step, True),
    ):
        count = round((top - bottom) / step)
        if not np.isclose(count * step, top - bottom, rtol=0.0, atol=1e-9):
            raise ValueError(f"step {step} m does not divide {bottom / KM:g}-{top / KM:g} km")
        parts.append(bottom + step * np.arange(count + int(closed)))
    return np.concatenate(parts)


def number_densities(z: FloatArray) -> dict[str, FloatArray]:
    """Number densities [1/m^3] of N2, O, O2, Ar, He and H on the increasing grid ``z`` [m].

    ``z`` must start at 86 km and contain 150 and 500 km (see :func:`altitude_grid`).
    """
    temperature, gradient = kinetic_temperature(z)
    g = gravity(z)
    k = eddy_diffusion(z)
    mixed = z < MIXING_TOP
    molecular_weight = np.where(mixed, SEA_LEVEL_MOLECULAR_WEIGHT, MOLECULAR_WEIGHT["N2"])
    temperature_ratio = T7 / temperature
    scale = g / (GAS_CONSTANT * temperature)  # g / (R* T) [kmol/(kg m)]

    n = {
        "N2": NUMBER_DENSITY_86KM["N2"]
        * temperature_ratio
        * np.exp(-cumulative_trapezoid(molecular_weight * scale, z, initial=0.0))
    }
    for species in ("O", "O2", "Ar", "He"):
        if species in ("O", "O2"):
            background, weight = n["N2"], molecular_weight
        else:
            # Ar and He diffuse through the N2-O-O2 mixture: above 100 km the weight in the
            # eddy term is that mixture's mean molecular weight.
            background = n["N2"] + n["O"] + n["O2"]
            mixture = (
                n["N2"] * MOLECULAR_WEIGHT["N2"]
                + n["O"] * MOLECULAR_WEIGHT["O"]
                + n["O2"] * MOLECULAR_WEIGHT["O2"]
            ) / background
            weight = np.where(mixed, SEA_LEVEL_MOLECULAR_WEIGHT, mixture)
        d = molecular_diffusion(species, background, temperature)
        f = (
            scale
            * d
            / (d + k)
            * (
                MOLECULAR_WEIGHT[species]
                + weight * k / d
                + THERMAL_DIFFUSION[species] * GAS_CONSTANT * gradient / g
            )
        )
        exponent = cumulative_trapezoid(f + flux_term(species, z), z, initial=0.0)
        n[species] = NUMBER_DENSITY_86KM[species] * temperature_ratio * np.exp(-exponent)
    n["H"] = _hydrogen(z, temperature, g, n)
    return n


def _hydrogen(
    z: FloatArray, temperature: FloatArray, g: FloatArray, n: dict[str, FloatArray]
) -> FloatArray:
    """Atomic hydrogen [1/m^3]: zero below 150 km, escape flux below 500 km (module notes)."""
    top = np.flatnonzero(z >= HYDROGEN_BASE)
    zh, th = z[top], temperature[top]
    i11 = int(np.flatnonzero(zh == Z11)[0])
    t11 = th[i11]
    tau = cumulative_trapezoid(
        MOLECULAR_WEIGHT["H"] * g[top] / (GAS_CONSTANT * th), zh, initial=0.0
    )
    tau -= tau[i11]  # int_Z11^Z
    background = sum(n[s][top] for s in ("N2", "O", "O2", "Ar", "He"))
    d = molecular_diffusion("H", background, th)
    power = 1.0 + THERMAL_DIFFUSION["H"]
    flux = HYDROGEN_FLUX / d * (th / t11) ** power * np.exp(tau)
    cumulative = cumulative_trapezoid(flux, zh, initial=0.0)
    from_z_to_z11 = np.where(zh < Z11, cumulative[i11] - cumulative, 0.0)
    hydrogen = np.zeros_like(z)
    hydrogen[top] = (HYDROGEN_500KM + from_z_to_z11) * (t11 / th) ** power * np.exp(-tau)
    return hydrogen


def mass_density(n: dict[str, FloatArray]) -> FloatArray:
    """Mass density [kg/m^3] from the number densities [1/m^3]."""
    return sum(n[s] * MOLECULAR_WEIGHT[s] for s in SPECIES) / AVOGADRO


def integrated_density(
    altitudes_km: Sequence[float], fine_step: float = FINE_STEP, coarse_step: float = COARSE_STEP
) -> FloatArray:
    """Integrated US76 mass density [kg/m^3] at geometric altitudes [km] in 86-1000 km.

    Log-linear between grid points; node altitudes are grid points, so exact there.
    """
    z = altitude_grid(fine_step, coarse_step)
    log_rho = np.log(mass_density(number_densities(z)))
    return np.exp(np.interp(np.asarray(altitudes_km, dtype=float) * KM, z, log_rho))


# -- The config's node list ------------------------------------------------------------------


def node_altitudes_km() -> list[float]:
    """Altitudes [km] of the config's density nodes above 86 km."""
    altitudes: list[float] = []
    for first, last, spacing in NODE_SPACING_KM:
        count = round((last - first) / spacing)
        altitudes += [first + i * spacing for i in range(count + 1)]
    return altitudes


def round_figures(value: float) -> float:
    """``value`` rounded to Table I's four significant figures."""
    return float(f"{value:.{SIGNIFICANT_FIGURES - 1}e}")


def nodes() -> list[Node]:
    """The config's nodes: published Table I entries, otherwise the rounded integration."""
    altitudes = node_altitudes_km()
    rho = integrated_density(altitudes)
    return [
        Node(z, TABLE_I_DENSITY[z], True)
        if z in TABLE_I_DENSITY
        else Node(z, round_figures(r), False)
        for z, r in zip(altitudes, rho, strict=True)
    ]


def format_node(node: Node) -> str:
    """One line of ``upper_density_nodes_km_kg_m3`` as the config writes it."""
    line = f"  - [{node.altitude_km!r}, {node.density_kg_m3:.{SIGNIFICANT_FIGURES - 1}e}]"
    return f"{line.ljust(COMMENT_COLUMN)}{TABLE_I_MARK}" if node.table_i else line


_NODE_LINE = re.compile(r"^\s*-\s*\[\s*([^,\s]+)\s*,\s*([^\]\s]+)\s*\]\s*(#.*)?$")


def read_config_nodes(path: Path = DEFAULT_CONFIG) -> list[Node]:
    """The ``upper_density_nodes_km_kg_m3`` list of a config file, with its Table I marks.

    Read as text (the marks are comments): the list items after the key, up to the next key.
    """
    found: list[Node] = []
    inside = False
    for raw in path.read_text(encoding="utf-8").splitlines():
        if raw.startswith("upper_density_nodes_km_kg_m3:"):
            inside = True
            continue
        if not inside or not raw.strip() or raw.lstrip().startswith("#"):
            continue
        match = _NODE_LINE.match(raw)
        if match is None:
            break
        altitude, density, comment = match.groups()
        found.append(Node(float(altitude), float(density), TABLE_I_MARK in (comment or "")))
    if not found:
        raise ValueError(f"no upper_density_nodes_km_kg_m3 list in {path}")
    return found


def check(path: Path = DEFAULT_CONFIG) -> tuple[list[str], str]:
    """Compare a config's nodes with this script's: (problems, empty if none; a summary)."""
    config = read_config_nodes(path)
    altitudes = [node.altitude_km for node in config]
    if altitudes != node_altitudes_km():
        return [f"node altitudes differ: config {altitudes}, script {node_altitudes_km()}"], ""
    problems = []
    worst_figure = worst_table = 0.0
    for node, rho in zip(config, integrated_density(altitudes), strict=True):
        published = TABLE_I_DENSITY.get(node.altitude_km)
        if node.table_i != (published is not None):
            problems.append(f"{node.altitude_km} km: Table I mark differs from the script's")
        elif published is not None:
            if node.density_kg_m3 != published:
                problems.append(
                    f"{node.altitude_km} km: {node.density_kg_m3} != Table I {published}"
                )
            deviation = abs(rho / published - 1.0)
            worst_table = max(worst_table, deviation)
            if deviation > TABLE_I_TOLERANCE:
                problems.append(
                    f"{node.altitude_km} km: integration {rho:.5e} vs Table I {published}"
                )
        else:
            unit = 10.0 ** (np.floor(np.log10(node.density_kg_m3)) - (SIGNIFICANT_FIGURES - 1))
            figures = abs(rho - node.density_kg_m3) / unit  # in units of the 4th figure
            worst_figure = max(worst_figure, figures)
            if figures > 0.5:
                problems.append(f"{node.altitude_km} km: config {node.density_kg_m3} vs {rho:.5e}")
    summary = (
        f"{len(config)} nodes; computed: worst {worst_figure:.3f} units of the 4th figure "
        f"(0.5 allowed); Table I: worst {100 * worst_table:.3f} % "
        f"({100 * TABLE_I_TOLERANCE:g} % allowed)"
    )
    return problems, summary


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--check",
        nargs="?",
        const=DEFAULT_CONFIG,
        type=Path,
        metavar="CONFIG",
        help=f"compare with a config file (default {DEFAULT_CONFIG.relative_to(REPO_ROOT)})",
    )
    args = parser.parse_args(argv)
    if args.check is None:
        print("upper_density_nodes_km_kg_m3:")
        print("\n".join(format_node(node) for node in nodes()))
        return 0
    problems, summary = check(args.check)
    print(summary)
    for problem in problems:
        print(problem, file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
