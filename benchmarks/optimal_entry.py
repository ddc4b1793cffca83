"""Optimal entry (issue 8): our pseudospectral solver against an independent transcription.

The peer is written here from scratch with CasADi's ``Opti`` stack and shares no code with
``ovtraj.reentry.pseudospectral``: Hermite-Simpson collocation (separated form, Betts,
*Practical Methods for Optimal Control*, 2nd ed., 2010, sec. 4.6.6) in time with a free
final time, states ``(h, lon, lat, V, gamma, psi)``, controls at the mesh points and
midpoints, path constraints at both, its own US76 closed form (0-86 km, NOAA-S/T
76-1562 eqs. 18, 23, 33a/b, 42, 50, read from ``configs/atmosphere_us76.yaml``), its own
downrange formula, a straight-line initial guess. It poses the published case of seed
001 from the same YAML file (``configs/cases/suborbital_return.yaml``).

Printed: objective (range), NLP iterations, wall time (NLP construction + solve) and the
ratios. Goals (issue 8): our objective within 0.1 % of the peer's, our solve under 2 s.

Run: ``python benchmarks/optimal_entry.py [--intervals 150]``.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import casadi as ca
import numpy as np
import yaml

from ovtraj.reentry.pseudospectral import load_optimal_entry, solve_optimal_entry

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "configs" / "cases" / "suborbital_return.yaml"
US76 = ROOT / "configs" / "atmosphere_us76.yaml"
EARTH = ROOT / "configs" / "earth.yaml"
OBJECTIVE_GOAL = 0.001  # issue 8: objectives equal within 0.1 %
TIME_GOAL_S = 2.0  # issue 8: our solve under 2 s
DEFAULT_INTERVALS = 150  # Hermite-Simpson intervals of the peer (300 control points)
REPEATS = 3  # timed solves of ours (median); the first also warms up the imports
# The peer's own starting point: a straight line in the states between the initial and
# terminal conditions over about 800 km (0.13 rad of longitude, due east), 500 s, alpha
# 15 deg, no bank; nothing taken from our solver's guess.
PEER_GUESS_TIME_S = 500.0
PEER_GUESS_ALPHA_DEG = 15.0
PEER_GUESS_ARC_RAD = 0.13
PEER_OBJECTIVE_SCALE_RAD = 0.1  # downrange of order 0.1 rad: scaled objective ~ 1
PEER_IPOPT = {"print_level": 0, "sb": "yes", "tol": 1e-8, "max_iter": 3000}


def us76_density_sound(z: ca.MX | ca.SX, table: dict) -> tuple:
    """US76 density [kg/m^3] and speed of sound [m/s] below 86 km, as CasADi expressions."""
    r0 = table["earth_radius_m"]
    gas = table["gas_constant_J_kmol_K"]
    m0 = table["sea_level_molecular_weight_kg_kmol"]
    k = table["geopotential_gravity_m_s2"] * m0 / gas
    bases = [1e3 * b for b in table["layer_base_geopotential_height_km"]]
    lapses = [1e-3 * lapse for lapse in table["layer_lapse_rate_K_per_km"]]
    temps, pressures = [table["sea_level_temperature_K"]], [table["sea_level_pressure_Pa"]]
    for i in range(len(bases) - 1):
        dh = bases[i + 1] - bases[i]
        t_top = temps[i] + lapses[i] * dh
        if lapses[i] == 0.0:
            pressures.append(pressures[i] * math.exp(-k * dh / temps[i]))
        else:
            pressures.append(pressures[i] * (temps[i] / t_top) ** (k / lapses[i]))
        temps.append(t_top)
    hgeo = r0 * z / (r0 + z)
    rho, sound = None, None
    for i in range(len(bases)):
        top = bases[i + 1] if i + 1 < len(bases) else 1e6
        dh = ca.fmin(ca.fmax(hgeo, bases[i]), top) - bases[i]
        temperature = temps[i] + lapses[i] * dh
        if lapses[i] == 0.0:
            pressure = pressures[i] * ca.exp(-k * dh / temps[i])
        else:
            pressure = pressures[i] * (temps[i] / temperature) ** (k / lapses[i])
        layer_rho = pressure * m0 / (gas * temperature)
        layer_sound = ca.sqrt(table["ratio_of_specific_heats"] * gas * temperature / m0)
        if rho is None:
            rho, sound = layer_rho, layer_sound
        else:
            inside = hgeo >= bases[i]
            rho = ca.if_else(inside, layer_rho, rho)
            sound = ca.if_else(inside, layer_sound, sound)
    return rho, sound


def peer_solve(intervals: int) -> dict:
    """The published case by Hermite-Simpson in time (see the module notes)."""
    case = yaml.safe_load(CASE.read_text(encoding="utf-8"))
    table = yaml.safe_load(US76.read_text(encoding="utf-8"))
    earth = yaml.safe_load(EARTH.read_text(encoding="utf-8"))
    # float(): PyYAML reads "3.986004418e14" (no exponent sign) as a string.
    mu, re_, g0 = (float(earth[k]) for k in ("mu_m3_s2", "equatorial_radius_m", "g0_m_s2"))
    veh, ini, term = case["vehicle"], case["initial"], case["terminal"]
    mass, area = veh["mass_kg"], veh["reference_area_m2"]
    cl_c, cd_c = veh["aero"]["cl"], veh["aero"]["cd"]
    path, heat = case["path"], case["path"]["heat_rate"]
    deg = math.pi / 180.0
    lon0, lat0, psi0 = (
        ini["longitude_deg"] * deg,
        ini["latitude_deg"] * deg,
        ini["heading_deg"] * deg,
    )

    def rhs(x, u):
        h, _, lat, v, gam, psi = (x[i] for i in range(6))
        alpha, bank = u[0], u[1]
        rho, sound = us76_density_sound(h, table)
        a_deg, mach = alpha / deg, v / sound
        cl = sum(cl_c[i][j] * a_deg**i * mach**j for i in range(3) for j in range(2))
        cd = sum(cd_c[i][j] * a_deg**i * mach**j for i in range(3) for j in range(2))
        q = 0.5 * rho * v**2
        lift, drag = q * area * cl / mass, q * area * cd / mass
        r = re_ + h
        g = mu / r**2
        dx = ca.vertcat(
            v * ca.sin(gam),
            v * ca.cos(gam) * ca.sin(psi) / (r * ca.cos(lat)),
            v * ca.cos(gam) * ca.cos(psi) / r,
            -drag - g * ca.sin(gam),
            (lift * ca.cos(bank) + (v**2 / r - g) * ca.cos(gam)) / v,
            (lift * ca.sin(bank) / ca.cos(gam) + v**2 / r * ca.cos(gam) * ca.sin(psi) * ca.tan(lat))
            / v,
        )
        load = (lift * ca.cos(alpha) + drag * ca.sin(alpha)) / g0
        qdot = heat["coefficient"] * rho ** heat["density_exponent"] * v ** heat["speed_exponent"]
        return dx, ca.vertcat(load, q, qdot)

    xs, us = ca.MX.sym("x", 6), ca.MX.sym("u", 2)
    dx, pc = rhs(xs, us)
    f = ca.Function("f", [xs, us], [dx, pc]).expand()

    n = intervals
    opti = ca.Opti()
    x = opti.variable(6, n + 1)
    xm = opti.variable(6, n)
    u = opti.variable(2, n + 1)
    um = opti.variable(2, n)
    tf = opti.variable()
    scale = ca.DM([ini["altitude_km"] * 1e3, 1, 1, ini["speed_mps"], 1, 1])
    X, XM = x * ca.repmat(scale, 1, n + 1), xm * ca.repmat(scale, 1, n)
    fx, px = f.map(n + 1)(X, u)
    fm, pm = f.map(n)(XM, um)
    dt = tf / n
    left, right = X[:, :-1], X[:, 1:]
    opti.subject_to(
        ca.vec(
            (XM - 0.5 * (left + right) - dt / 8 * (fx[:, :-1] - fx[:, 1:])) / ca.repmat(scale, 1, n)
        )
        == 0
    )
    opti.subject_to(
        ca.vec((right - left - dt / 6 * (fx[:, :-1] + 4 * fm + fx[:, 1:])) / ca.repmat(scale, 1, n))
        == 0
    )
    start = [ini["altitude_km"] * 1e3, lon0, lat0, ini["speed_mps"], ini["fpa_deg"] * deg, psi0]
    opti.subject_to(X[:, 0] == ca.DM(start))
    opti.subject_to(X[0, -1] == term["altitude_km"]["value"] * 1e3)
    opti.subject_to(X[3, -1] == term["speed_mps"]["value"])
    opti.subject_to(X[4, -1] == term["fpa_deg"]["value"] * deg)
    sb, ctl = case["state_bounds"], case["controls"]
    for row, key, factor in ((0, "altitude_km", 1e3), (4, "fpa_deg", deg), (3, "speed_mps", 1.0)):
        lo, hi = sb[key]
        for var in (X, XM):
            opti.subject_to(opti.bounded(lo * factor, var[row, :], hi * factor))
    for row, key in ((0, "alpha"), (1, "bank")):
        lo, hi = ctl[key]["lower_deg"] * deg, ctl[key]["upper_deg"] * deg
        opti.subject_to(opti.bounded(lo, u[row, :], hi))
        opti.subject_to(opti.bounded(lo, um[row, :], hi))
    limits = [path["max_load_g"], path["max_dynamic_pressure_kpa"] * 1e3, heat["max_kw_m2"] * 1e3]
    for k, limit in enumerate(limits):
        opti.subject_to(opti.bounded(-1, px[k, :] / limit, 1))
        opti.subject_to(opti.bounded(-1, pm[k, :] / limit, 1))
    t_lo, t_hi = case["transcription"]["final_time_bounds_s"]
    opti.subject_to(opti.bounded(t_lo, tf, t_hi))

    # Downrange: arc along the initial great circle to the foot of the final point.
    p0 = np.array(
        [math.cos(lat0) * math.cos(lon0), math.cos(lat0) * math.sin(lon0), math.sin(lat0)]
    )
    east = np.array([-math.sin(lon0), math.cos(lon0), 0.0])
    north = np.cross(p0, east)
    along = math.cos(psi0) * north + math.sin(psi0) * east
    lon_f, lat_f = X[1, -1], X[2, -1]
    pf = ca.vertcat(ca.cos(lat_f) * ca.cos(lon_f), ca.cos(lat_f) * ca.sin(lon_f), ca.sin(lat_f))
    downrange = ca.atan2(ca.dot(ca.DM(along), pf), ca.dot(ca.DM(p0), pf))
    opti.minimize(-downrange / PEER_OBJECTIVE_SCALE_RAD)

    # Straight-line guess (see PEER_GUESS_*).
    end = [
        term["altitude_km"]["value"] * 1e3,
        lon0 + PEER_GUESS_ARC_RAD,
        lat0,
        term["speed_mps"]["value"],
        term["fpa_deg"]["value"] * deg,
        psi0,
    ]
    frac = np.linspace(0.0, 1.0, n + 1)
    guess = np.outer(start, 1 - frac) + np.outer(end, frac)
    opti.set_initial(x, guess / np.array(scale).reshape(-1, 1))
    mid = 0.5 * (guess[:, :-1] + guess[:, 1:])
    opti.set_initial(xm, mid / np.array(scale).reshape(-1, 1))
    opti.set_initial(u[0, :], PEER_GUESS_ALPHA_DEG * deg)
    opti.set_initial(um[0, :], PEER_GUESS_ALPHA_DEG * deg)
    opti.set_initial(tf, PEER_GUESS_TIME_S)
    opti.solver(
        "ipopt",
        {"expand": True, "print_time": False},
        PEER_IPOPT,
    )
    t0 = time.perf_counter()
    try:
        sol = opti.solve()
        value = sol.value
        stats = sol.stats()
    except RuntimeError:
        value = opti.debug.value
        stats = opti.stats()
    elapsed = time.perf_counter() - t0
    return {
        "objective_km": float(value(downrange)) * re_ / 1e3,
        "iterations": int(stats["iter_count"]),
        "time_s": elapsed,
        "status": stats["return_status"],
        "final_time_s": float(value(tf)),
    }


def ours(independent: str | None = None) -> dict:
    problem = load_optimal_entry(CASE)
    runs = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        result = solve_optimal_entry(problem, independent=independent)
        runs.append((time.perf_counter() - start, result))
    times = sorted(r.solve_time_s for _, r in runs)
    result = runs[-1][1]
    return {
        "objective_km": result.objective_value,
        "iterations": result.nlp_iterations,
        "time_s": times[len(times) // 2],
        "build_s": result.nlp_build_time_s,
        "ipopt_s": result.nlp_solve_time_s,
        "status": result.status,
        "final_time_s": result.final_time_s,
        "label": f"ours, {result.independent}, {result.method.upper()} "
        f"{result.segments}x{result.nodes_per_segment}",
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--intervals", type=int, default=DEFAULT_INTERVALS)
    args = parser.parse_args()
    peer = peer_solve(args.intervals)
    peer["label"] = f"peer, Opti Hermite-Simpson, {args.intervals} intervals"
    rows = [ours(), ours("time"), peer]
    print(
        f"{'solver':44s} {'range [km]':>11s} {'ratio':>9s} {'tf [s]':>8s} "
        f"{'iter':>5s} {'time [s]':>9s}  status"
    )
    for row in rows:
        ratio = row["objective_km"] / peer["objective_km"]
        print(
            f"{row['label']:44s} {row['objective_km']:11.3f} {ratio:9.5f} "
            f"{row['final_time_s']:8.2f} {row['iterations']:5d} {row['time_s']:9.3f}  "
            f"{row['status']}"
        )
    mine = rows[0]
    gap = abs(mine["objective_km"] / peer["objective_km"] - 1.0)
    print(
        f"\nours: {mine['time_s']:.3f} s median of {REPEATS} (guess + NLP build "
        f"{mine['build_s']:.3f} s + IPOPT {mine['ipopt_s']:.3f} s + ...); "
        f"peer / ours time ratio {peer['time_s'] / mine['time_s']:.2f}"
    )
    print(
        f"goal objective within {OBJECTIVE_GOAL:.1%}: {gap:.4%} "
        f"{'met' if gap <= OBJECTIVE_GOAL else 'NOT met'}; goal solve under {TIME_GOAL_S:g} s: "
        f"{'met' if mine['time_s'] < TIME_GOAL_S else 'NOT met'}"
    )
    print("published (seed 001): 844.15 km")


if __name__ == "__main__":
    main()
