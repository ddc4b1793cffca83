"""The launch solved at one parking altitude, not read from the fit, and cached.

The mission chain takes the launch from the launch fit (patent 5.1): payload, times
and the insertion's argument of latitude, with an idealised insertion on the circular
orbit. A plan that flies from the carrier's drop needs the programme itself: the ten
design variables of the stage's optimisation (patent step 101) at the design's exact
parking altitude.

:func:`solve_launch_at` solves it by one continuation step from the fit's solved grid,
as the grid itself was solved (:mod:`ovtraj.launch.launch_fit`):
- the secant through the two grid launches that bracket the altitude predicts the
  design;
- the stage's local phases (SLSQP, then trust-constr) start from that prediction,
  keeping the optimum on the grid's branch (a fresh genetic search could land on
  another local optimum).
Without a grid (a fit carried by its coefficients only), or when that step fails, the
stage's full genetic plus local search runs instead.

:func:`cached_launch_at` stores the solved launch as a product in the workspace: the
stage's row without its timing, plus a marker with the file's digest, checked on every
read. Its key is the content hash of everything the launch depends on (the launch fit's
key), the altitude and the code version, so that a plan, a replan or a replay of the
same design solves it once.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ovtraj.astro.frames import ecef_to_eci_state
from ovtraj.config import Scenario
from ovtraj.config.launch import DESIGN_VARIABLES
from ovtraj.config.mission import LaunchMatchSettings
from ovtraj.launch.ascent import initial_state
from ovtraj.launch.frame import launch_frame_axes, launch_to_ecef
from ovtraj.launch.inputs import LaunchInput, launch_input
from ovtraj.launch.insertion import MATCH_PHASE, InsertionPoint, solve_launch_to
from ovtraj.launch.launch_fit import LaunchFit, design_of, launch_fit_key, predicted_design
from ovtraj.launch.result import PHASES, LaunchResult
from ovtraj.launch.stage import ascent_model, solve_launch
from ovtraj.paths import workspace
from ovtraj.store.files import StoreError
from ovtraj.store.products import Product
from ovtraj.version import code_version

__all__ = [
    "SolvedLaunch",
    "cached_launch_at",
    "cached_launch_to",
    "drop_state",
    "grid_prediction",
    "launch_solve_key",
    "solve_launch_at",
    "solve_launch_to_point",
]

KIND = "launch-solve"
MARKER = "meta.json"
ROW_FILE = "launch.json"
# Wall times of the solve: never part of a stored result.
TIMING_KEYS = frozenset(
    {"wall_time_s", *(f"{p.replace('-', '_')}_time_s" for p in (*PHASES, MATCH_PHASE))}
)


def launch_solves_root() -> Path:
    """Where solved launches are cached: the workspace's ``launch_solves``."""
    return workspace() / "launch_solves"


def launch_solve_key(scenario: Scenario, altitude_m: float) -> str:
    """Content hash of the launch problem at ``altitude_m`` and the code that solves it."""
    content = {
        "launch": launch_fit_key(scenario),
        "altitude_m": repr(float(altitude_m)),
        "code": code_version(),
    }
    text = json.dumps(content, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def grid_prediction(fit: LaunchFit, altitude_m: float) -> dict[str, float] | None:
    """The programme at ``altitude_m`` predicted from the fit's solved grid: the secant
    through the two nearest feasible grid launches (None without two of them)."""
    grid = fit.grid
    if grid.empty or "target_altitude_km" not in grid.columns:
        return None
    grid = grid[grid["feasible"].astype(bool)].sort_values("target_altitude_km")
    heights = grid["target_altitude_km"].to_numpy(dtype=float) * 1e3
    if len(heights) < 2:
        return None
    # The two nearest solved launches: the nearer seeds, the other gives the secant.
    order = np.argsort(np.abs(heights - altitude_m), kind="stable")[:2]
    rows = [grid.iloc[int(k)].to_dict() for k in order]
    return predicted_design(
        altitude_m,
        (heights[order[0]], design_of(rows[0])),
        (heights[order[1]], design_of(rows[1])),
    )


def solve_launch_at(scenario: Scenario, fit: LaunchFit, altitude_m: float) -> LaunchResult:
    """The stage's optimum at ``altitude_m`` by continuation from the fit's grid."""
    inp = launch_input(scenario, altitude_km=altitude_m / 1e3)
    seed = grid_prediction(fit, altitude_m)
    if seed is None:
        return solve_launch(inp)
    result = solve_launch(inp, seed_design=seed, global_search=False)
    return result if result.feasible else solve_launch(inp)


def solve_launch_to_point(
    scenario: Scenario,
    fit: LaunchFit,
    altitude_m: float,
    point: InsertionPoint,
    raan_offset_rad: float,
    settings: LaunchMatchSettings,
) -> LaunchResult:
    """The launch flown to the chain's insertion ``point`` (:mod:`ovtraj.launch.insertion`),
    from the grid's prediction at ``altitude_m`` (else the stage's optimum there), in the
    target's plane turned ``raan_offset_rad`` east (the plane the chain aimed at)."""
    inp = launch_input(scenario, altitude_km=altitude_m / 1e3)
    inp = replace(inp, target_plane=inp.target_plane.turned(raan_offset_rad))
    seed = grid_prediction(fit, altitude_m)
    if seed is None:
        start = solve_launch(inp)
        if not start.feasible:
            return start
        seed = start.design
    return solve_launch_to(inp, point, seed, settings)


@dataclass(frozen=True)
class SolvedLaunch:
    """A solved launch as the plan uses it (the stage's row, timing removed)."""

    row: dict[str, Any]

    @property
    def feasible(self) -> bool:
        return bool(self.row["feasible"])

    @property
    def reason(self) -> str | None:
        return self.row.get("reason")

    @property
    def altitude_m(self) -> float:
        return float(self.row["target_altitude_km"]) * 1e3

    @property
    def design(self) -> dict[str, float]:
        """The ten programme variables, configuration units (``design_<name>`` columns)."""
        return {name: float(self.row[f"design_{name}"]) for name in DESIGN_VARIABLES}

    def value(self, key: str) -> float:
        return float(self.row[key])

    @property
    def insertion_state(self) -> np.ndarray:
        """ECI position [m] and velocity [m/s] at insertion (the solved ascent's end)."""
        return np.array(
            [self.row[f"insertion_r_eci_{axis}_m"] for axis in "xyz"]
            + [self.row[f"insertion_v_eci_{axis}_mps"] for axis in "xyz"],
            dtype=float,
        )


def _row_of(result: LaunchResult) -> dict[str, Any]:
    return {k: v for k, v in result.to_row().items() if k not in TIMING_KEYS}


def cached_launch_at(
    scenario: Scenario, fit: LaunchFit, altitude_m: float, root: Path | None = None
) -> SolvedLaunch:
    """The launch at ``altitude_m``: read from the cache, or solved and stored there.

    Raises :class:`~ovtraj.store.files.StoreError` naming the file when a cached product fails
    its checksum (nothing is solved over it) or cannot be written.
    """
    key = launch_solve_key(scenario, altitude_m)
    return _cached(
        key, altitude_m, root, lambda: _row_of(solve_launch_at(scenario, fit, altitude_m))
    )


def cached_launch_to(
    scenario: Scenario,
    fit: LaunchFit,
    altitude_m: float,
    point: InsertionPoint,
    raan_offset_rad: float,
    root: Path | None = None,
) -> SolvedLaunch:
    """The launch flown to ``point`` (:func:`solve_launch_to_point`, the settings of
    ``mission.insertion.launch_match``): read from the cache, or solved and stored there.
    Its key adds the point, the node offset and those settings to :func:`launch_solve_key`'s
    content. Raises :class:`~ovtraj.store.files.StoreError` as :func:`cached_launch_at`."""
    settings = scenario.mission.insertion.launch_match
    content = {
        "solve": launch_solve_key(scenario, altitude_m),
        "point": [repr(float(point.t_s)), repr(float(point.flight_time_s))]
        + [repr(float(v)) for v in point.state],
        "raan_offset_rad": repr(float(raan_offset_rad)),
        "match": settings.model_dump(mode="json", exclude={"time_limit_s"}),
    }
    text = json.dumps(content, sort_keys=True, separators=(",", ":"))
    key = hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]

    def solve() -> dict[str, Any]:
        result = solve_launch_to_point(scenario, fit, altitude_m, point, raan_offset_rad, settings)
        return {**_row_of(result), "raan_offset_deg": math.degrees(raan_offset_rad)}

    return _cached(key, altitude_m, root, solve)


def _cached(
    key: str, altitude_m: float, root: Path | None, solve: Callable[[], dict[str, Any]]
) -> SolvedLaunch:
    product = Product((root or launch_solves_root()) / key, MARKER)
    if product.exists():
        marker = product.marker()
        if marker.get("kind") != KIND or marker.get("key") != key:
            raise StoreError(f"{product.marker_path}: not the launch solve {key}")
        row = product.read_json(ROW_FILE, marker)
        if not isinstance(row, dict) or "feasible" not in row:
            raise StoreError(f"{product.directory / ROW_FILE}: not a launch row")
        return SolvedLaunch(row)
    row = solve()
    with product.writing() as writer:
        writer.write_json(ROW_FILE, row)
        writer.finish({"kind": KIND, "key": key, "altitude_m": float(altitude_m)})
    return SolvedLaunch(row)


def drop_state(
    inp: LaunchInput, azimuth_rad: float, payload_kg: float, drop_time_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """ECI position [m] and inertial velocity [m/s] of the carrier's drop, ``drop_time_s``
    after the launch day's 0 h: the ascent's own initial state (its drop point, Mach and
    path angle along the azimuth), out of the launch frame."""
    model = ascent_model(inp)
    y0 = initial_state(model, 1, np.array([payload_kg]))[:, 0]
    axes = launch_frame_axes(model.drop.latitude_rad, model.drop.longitude_rad, azimuth_rad)
    r_ecef, v_ecef = launch_to_ecef(y0[0:3], y0[3:6], axes, radius_m=inp.earth.radius)
    theta = inp.launch_day.gmst_rad() + inp.earth.omega * drop_time_s
    r, v = ecef_to_eci_state(r_ecef, v_ecef, theta, omega=inp.earth.omega)
    return np.asarray(r, dtype=float), np.asarray(v, dtype=float)
