"""Write the example TLE of the default scenario's ISS-like target (configs/targets/).

The default scenario types its target's osculating elements by hand. The example
TLE states the same orbit as a two-line element set, as a catalogue would publish
it, for the worked re-plan of the README: SGP4 mean elements (WGS-72, Kozai mean
motion) at the scenario epoch, fitted by least squares so that SGP4 reproduces the
hand-typed osculating state at the epoch (position and velocity), with B* = 0
(no drag term: the project's chain has none). It is synthetic, not a published set.

Run: ``python tools/example_tle.py`` (prints the path it wrote).

``python tools/example_tle.py --nights N --first-day -3 --out DIR`` writes the element
sets of a drifting target for a re-plan history (docs/tracking.md): the same orbit,
propagated from the scenario epoch with the project's J2 propagator (DOP853, rtol 1e-12)
to each night's epoch (``first-day``, ``first-day + 1``, ... days from the scenario
epoch) and fitted there as above, one ``iss-like-<date>.tle`` per night. A night's set
differs from the previous one as a catalogue's does: a new epoch, the node regressed by
J2, another mean anomaly.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares
from sgp4.api import WGS72, Satrec
from sgp4.exporter import export_tle

from ovtraj.astro.angles import TWO_PI
from ovtraj.astro.epoch import Epoch
from ovtraj.target_sources import load_scenario
from ovtraj.target_state import target_state

ROOT = Path(__file__).resolve().parents[1]
OUTPUT = ROOT / "configs" / "targets" / "iss-like-2026-12-01.tle"
# SGP4 epochs count days from 1949-12-31 00:00 UT.
SGP4_EPOCH0 = Epoch.from_iso("1949-12-31T00:00:00Z")


def _satrec(x: np.ndarray, epoch_days: float) -> Satrec:
    """SGP4 of nonsingular mean elements ``(n [rad/min], ex, ey, i, raan, u) [rad]``."""
    n, ex, ey, i, raan, u = x
    argp = math.atan2(ey, ex) % TWO_PI
    sat = Satrec()
    sat.sgp4init(
        WGS72,
        "i",
        99999,
        epoch_days,
        0.0,
        0.0,
        0.0,
        math.hypot(ex, ey),
        argp,
        i,
        (u - argp) % TWO_PI,
        n,
        raan % TWO_PI,
    )
    return sat


def fitted_tle(scenario, state: np.ndarray, epoch: Epoch) -> tuple[str, str, float]:
    """SGP4 lines fitted to the Cartesian ``state`` [m, m/s] at ``epoch``, and the
    position residual [m]."""
    days = epoch.seconds_since(SGP4_EPOCH0) / 86400.0
    orbit = scenario.target.orbit
    a = orbit.semi_major_axis_km
    u = math.radians(orbit.arg_perigee_deg + orbit.true_anomaly_deg)
    argp = math.radians(orbit.arg_perigee_deg)
    guess = np.array(
        [
            math.sqrt(398600.8 / a**3) * 60.0,  # rad/min
            orbit.eccentricity * math.cos(argp),
            orbit.eccentricity * math.sin(argp),
            math.radians(orbit.inclination_deg),
            math.radians(orbit.raan_deg),
            u,
        ]
    )

    if epoch != scenario.epoch:  # the hand-typed angles are the epoch's: start from the state
        r, v = state[:3], state[3:]
        h = np.cross(r, v)
        raan = math.atan2(h[0], -h[1])
        node = np.array([math.cos(raan), math.sin(raan), 0.0])
        u_now = math.atan2(np.dot(np.cross(node, r), h) / np.linalg.norm(h), np.dot(node, r))
        guess[4], guess[5] = raan, u_now

    def residual(x: np.ndarray) -> np.ndarray:
        error, r, v = _satrec(x, days).sgp4(epoch.jd1, epoch.jd2)
        if error:
            return np.full(6, 1e6)
        return np.r_[np.subtract(r, state[:3] / 1e3), np.subtract(v, state[3:] / 1e3) * 1e3]

    fit = least_squares(residual, guess, x_scale=[1e-3, 1e-4, 1e-4, 1e-3, 1e-3, 1e-3])
    line1, line2 = export_tle(_satrec(fit.x, days))
    return line1, line2, float(np.linalg.norm(fit.fun[:3]) * 1e3)


def main() -> None:
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nights", type=int, default=0, help="drifting sets, one a day")
    parser.add_argument("--first-day", type=float, default=0.0, help="days from the epoch")
    parser.add_argument("--out", type=Path, default=OUTPUT.parent)
    args = parser.parse_args()
    scenario = load_scenario(ROOT / "configs" / "scenario.yaml")
    state = target_state(scenario.target.orbit, scenario)  # ECI = TEME (docs/targets.md)
    if args.nights <= 0:
        line1, line2, residual = fitted_tle(scenario, state, scenario.epoch)
        OUTPUT.parent.mkdir(parents=True, exist_ok=True)
        OUTPUT.write_text(f"ISS-LIKE (SYNTHETIC, tools/example_tle.py)\n{line1}\n{line2}\n")
        print(f"{OUTPUT} (epoch residual {residual:.1f} m)")
        return
    from ovtraj.astro.propagation.reference import propagate_dop853

    earth = scenario.earth  # the scenario's Earth, as its chain's
    args.out.mkdir(parents=True, exist_ok=True)
    for night in range(args.nights):
        dt = (args.first_day + night) * 86400.0
        moved = (
            propagate_dop853(
                state, 0.0, dt, mu=earth.mu, radius=earth.radius, j2=earth.j2, rtol=1e-12, atol=1e-6
            )
            if dt
            else state
        )
        epoch = scenario.epoch.plus_seconds(dt)
        line1, line2, residual = fitted_tle(scenario, moved, epoch)
        path = args.out / f"iss-like-{epoch.iso()[:10]}.tle"
        path.write_text(f"ISS-LIKE (SYNTHETIC, tools/example_tle.py)\n{line1}\n{line2}\n")
        print(f"{path.resolve()} (epoch {epoch.iso()}, residual {residual:.1f} m)")


if __name__ == "__main__":
    main()
