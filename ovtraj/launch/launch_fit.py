"""Launch fit (patent 5.1): the launch solved on a grid of target altitudes, then a
Fourier series per output.

The whole-mission optimisation needs, for a parking altitude ``h``, the payload,
the time from the launch day's 0 h to insertion and the argument of latitude at
insertion. Solving the launch there is too slow, so the patent fits

    f(h) = a0 + sum_{k=1..8} (a_k cos(k w h) + b_k sin(k w h))

to each output over a grid of solved launches (:mod:`.fourier`). The grid is solved
by continuation: the reference altitude (the scenario's target) gets the full
genetic + local search, and the other altitudes are solved outward from it, each
from its neighbour's optimum with the local phases only, so that every point lies
on the same branch of optima (a fresh global search per point could land on a
different local optimum and put a kink in the curve). The upward and downward
chains are independent and run in parallel in the Prefect flow.

The argument of latitude is unwrapped along the grid before fitting and wrapped
into ``[0, 360)`` deg on evaluation.

**One grid, many launch days**. The ascent relative to the Earth does not
depend on the day or on the target's node: an ascent depends on the launcher, the drop,
the settings and the inclination of the plane it aims at; the day and the node only time
the drop (:func:`ovtraj.launch.stage.insertion_time_s`). So the expensive grid is solved
once, for the *grid day* (the campaign epoch's UTC date, :func:`grid_launch_day`) and
keyed by :func:`launch_grid_key` (the launch section without its day, the Earth model and
the target plane's mean inclination on that day: no day, no node); a day's fit is that
grid's designs flown again and timed on the day (:func:`retimed_launch_fit`, 2-5 s), then
fitted and stored under the day's own :func:`launch_fit_key` (:func:`day_launch_fit`).
The target's mean inclination moves by at most ~2e-5 deg over a year of J2 (600 times
under the insertion tolerance; docs/window.md), and every row is checked against the
day's tolerances again when it is flown.
"""

from __future__ import annotations

import hashlib
import json
import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ovtraj.astro.angles import TWO_PI
from ovtraj.astro.epoch import Epoch
from ovtraj.config import Scenario
from ovtraj.config.launch import DESIGN_VARIABLES, FitGridConfig
from ovtraj.launch.ascent_optimization import OptimisationOutcome
from ovtraj.launch.fourier import FourierSeries
from ovtraj.launch.fourier_fit import fit_fourier_series
from ovtraj.launch.inputs import LaunchInput, launch_input, target_plane_at
from ovtraj.launch.result import ROW_SCHEMA, LaunchResult
from ovtraj.launch.stage import finish_launch, launch_problem, solve_launch
from ovtraj.parallel import EVALUATION_BLAS_THREADS, blas_threads
from ovtraj.paths import reference_dir, workspace
from ovtraj.store.files import Digest, StoreError, read_json
from ovtraj.store.products import Product
from ovtraj.store.records import plain, table_from_rows

logger = logging.getLogger(__name__)

Progress = Callable[[int, int, str], None]
"""``on_progress(points solved, grid points, what is being solved now)``."""

# Store layout of LaunchFit.save: the series, the solved grid, and meta.json (written last,
# the files' digests).
STORE_FORMAT = 2
KIND = "launch-fit"
MARKER = "meta.json"
COEFFICIENTS_FILE = "coefficients.json"
GRID_FILE = "grid.parquet"
GRID_SCHEMA = ROW_SCHEMA
"""``grid.parquet``: one :meth:`~ovtraj.launch.result.LaunchResult.to_row` per altitude."""

FITTED_OUTPUTS = {
    "payload_kg": ("kg", "payload_kg"),
    "insertion_time_s": ("s", "insertion_time_s"),
    "insertion_u_deg": ("deg", "insertion_u_deg"),
    "flight_time_s": ("s", "flight_time_s"),  # drop to insertion: the mission's start
}
# The fitted outputs a launch day moves (the first in-plane drop after its 0 h); the
# payload, the flight time and the argument of latitude at insertion are the ascent's
# (a rotation about the pole leaves u), the same on every day (module notes).
DAY_OUTPUTS = ("insertion_time_s",)


def fit_roots() -> tuple[Path, Path]:
    """Where solved fits live: the workspace (written by the launch-fit flow and
    ``ovtraj launch-fit``), then the shipped reference data (read only)."""
    return workspace() / "launch_fit", reference_dir() / "launch_fit"


def grid_altitudes_m(fit: FitGridConfig) -> list[float]:
    return [h * 1e3 for h in fit.altitudes_km()]


def continuation_chains(altitudes_m: list[float], reference_m: float) -> tuple[list, list]:
    """Grid altitudes above and below the reference, each ordered outward from it."""
    up = sorted(h for h in altitudes_m if h > reference_m)
    down = sorted((h for h in altitudes_m if h < reference_m), reverse=True)
    return up, down


def solve_reference(
    inp: LaunchInput, on_progress: Callable[[int, int, str], None] | None = None
) -> LaunchResult:
    """Full genetic + local search at the input's own target altitude (``on_progress``:
    the optimiser's, :func:`~ovtraj.launch.stage.solve_launch`)."""
    return solve_launch(inp, on_progress=on_progress)


def predicted_design(
    altitude_m: float,
    seed: tuple[float, dict[str, float]],
    previous: tuple[float, dict[str, float]] | None = None,
) -> dict[str, float]:
    """Start of a continuation step: the neighbour's design, or the secant through two.

    ``seed`` and ``previous`` are ``(altitude_m, design)`` of the last two solved
    points of a chain (``seed`` the nearer). With both, the design is extrapolated
    linearly in altitude (the secant predictor of numerical continuation, Allgower
    and Georg, *Introduction to Numerical Continuation Methods*, sec. 2.2), which
    starts the local search a fraction of a tolerance from the new optimum instead
    of one grid step away; the optimiser clips it to the design bounds.
    """
    h1, d1 = seed
    if previous is None or abs(h1 - previous[0]) < 1e-9:
        return dict(d1)
    h0, d0 = previous
    ratio = (altitude_m - h1) / (h1 - h0)
    return {name: d1[name] + ratio * (d1[name] - d0[name]) for name in d1}


def solve_from(
    inp: LaunchInput,
    altitude_m: float,
    seed: LaunchResult,
    previous: LaunchResult | None = None,
    on_progress: Callable[[int, int, str], None] | None = None,
) -> LaunchResult:
    """Local search at ``altitude_m`` from the chain's last optima (continuation step)."""
    target = inp.at_altitude(altitude_m)
    if not seed.feasible or not seed.design:
        # nothing to continue from: search globally
        return solve_launch(target, on_progress=on_progress)
    before = None
    if previous is not None and previous.feasible and previous.design:
        before = (previous.target_altitude_m, previous.design)
    start = predicted_design(altitude_m, (seed.target_altitude_m, seed.design), before)
    return solve_launch(target, seed_design=start, global_search=False, on_progress=on_progress)


def solve_grid(
    inp: LaunchInput, fit: FitGridConfig, on_progress: Progress | None = None
) -> list[LaunchResult]:
    """Every grid altitude, serially (the flow runs the two chains in parallel); a log
    line (info) per solved altitude, ``on_progress`` during each solve."""
    up, down = continuation_chains(grid_altitudes_m(fit), inp.target_altitude_m)
    count = _GridCount(1 + len(up) + len(down), on_progress)
    reference = count.solved(solve_reference(inp, count.solving(inp.target_altitude_m)))
    results = {inp.target_altitude_m: reference}
    for chain in (up, down):
        previous, seed = None, reference
        for h in chain:
            solved = solve_from(inp, h, seed, previous, count.solving(h))
            previous, seed = seed, count.solved(solved)
            results[h] = seed
    wanted = grid_altitudes_m(fit)
    return [results[h] for h in sorted(results) if _on_grid(h, wanted)]


class _GridCount:
    """Grid points solved, reported to the log and to ``on_progress``."""

    def __init__(self, total: int, on_progress: Progress | None) -> None:
        self.total, self.done, self.on_progress = total, 0, on_progress

    def solving(self, altitude_m: float) -> Callable[[int, int, str], None] | None:
        """The optimiser's ``on_progress`` while ``altitude_m`` is solved."""
        if self.on_progress is None:
            return None
        report = self.on_progress
        report(self.done, self.total, f"{altitude_m / 1e3:g} km")

        def step(done: int, total: int, phase: str) -> None:
            report(self.done, self.total, f"{altitude_m / 1e3:g} km, {phase} {done}/{total}")

        return step

    def solved(self, result: LaunchResult) -> LaunchResult:
        self.done += 1
        logger.info(
            f"launch fit: {result.target_altitude_m / 1e3:g} km solved "
            f"({self.done}/{self.total}): "
            + (
                f"payload {result.payload_kg:.2f} kg"
                if result.feasible
                else f"infeasible ({result.reason})"
            )
            + f", {result.wall_time_s:.1f} s"
        )
        if self.on_progress is not None:
            self.on_progress(self.done, self.total, f"{result.target_altitude_m / 1e3:g} km")
        return result


def _on_grid(h: float, grid: list[float]) -> bool:
    return any(abs(h - g) < 1e-6 for g in grid)


@dataclass(frozen=True)
class LaunchFit:
    """Fourier fits of the launch outputs against target altitude, with their data."""

    series: dict[str, FourierSeries]
    grid: pd.DataFrame  # one row per solved altitude (LaunchResult.to_row())
    launcher: str
    ridges: dict[str, float] = field(default_factory=dict)  # the weight each fit kept
    key: str = ""  # launch_fit_key() of the scenario it was solved for

    @property
    def altitude_range_km(self) -> tuple[float, float]:
        s = next(iter(self.series.values()))
        return s.h_min_m / 1e3, s.h_max_m / 1e3

    def evaluate(self, altitude_m: float) -> dict[str, float]:
        """Fitted outputs at ``altitude_m``; outside the grid raises FourierRangeError."""
        out = {name: float(series(altitude_m)) for name, series in self.series.items()}
        out["insertion_u_deg"] %= 360.0
        return out

    def loo_relative_error(self, name: str) -> float:
        """Largest leave-one-out error over the output's range on the grid."""
        values = self.grid[FITTED_OUTPUTS[name][1]].to_numpy(dtype=float)
        if name == "insertion_u_deg":
            values = np.degrees(np.unwrap(np.radians(values)))
        return float(self.series[name].loo_max_error) / float(np.ptp(values))

    def to_dict(self) -> dict[str, Any]:
        return {
            "launcher": self.launcher,
            "key": self.key,
            "ridges": self.ridges,
            "series": {name: s.to_dict() for name, s in self.series.items()},
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> LaunchFit:
        """The fit of :meth:`to_dict` (the coefficients; the solved grid is not carried,
        so :attr:`grid` is empty): what a DoE task carries to a worker that has no fit on
        its disk. A malformed mapping raises ``ValueError`` naming the key."""
        try:
            series = {n: FourierSeries.from_dict(d) for n, d in data["series"].items()}
            launcher = data["launcher"]
        except (KeyError, TypeError, AttributeError) as err:
            raise ValueError(
                f"not a launch fit's coefficients ({type(err).__name__}: {err})"
            ) from None
        if not series:
            raise ValueError("not a launch fit's coefficients: no series")
        return cls(
            series=series,
            grid=pd.DataFrame(),
            launcher=str(launcher),
            ridges=dict(data.get("ridges", {})),
            key=str(data.get("key", "")),
        )

    def save(self, directory: str | Path) -> dict[str, Digest]:
        """``coefficients.json`` and ``grid.parquet`` (:data:`GRID_SCHEMA`), then ``meta.json``.

        ``meta.json`` is written last and lists both files' size and SHA-256 with the fit's
        key. A stored fit is never overwritten: saving the same fit again is a no-op, another
        one into its directory is refused (:class:`~ovtraj.store.files.StoreError`). Returns the
        digests, ``meta.json`` included.
        """
        grid = table_from_rows(self.grid.to_dict(orient="records"), GRID_SCHEMA, "launch grid")
        with Product(directory, MARKER).writing() as out:
            out.write_json(COEFFICIENTS_FILE, self.to_dict())
            out.write_table(GRID_FILE, grid, GRID_SCHEMA)
            out.finish(
                {"format": STORE_FORMAT, "kind": KIND, "key": self.key, "launcher": self.launcher}
            )
        return dict(out.files)

    @classmethod
    def load(cls, directory: str | Path) -> LaunchFit:
        """A fit written by :meth:`save`; every file checked against ``meta.json`` (size,
        SHA-256, the grid's schema): StoreError names a missing or changed file."""
        product = Product(directory, MARKER)
        meta = product.marker()
        if meta.get("format") != STORE_FORMAT or meta.get("kind") != KIND:
            raise StoreError(f"{product.marker_path}: not a launch fit of format {STORE_FORMAT}")
        data = product.read_json(COEFFICIENTS_FILE, meta)
        try:
            series = {n: FourierSeries.from_dict(d) for n, d in data["series"].items()}
            launcher = data["launcher"]
        except (KeyError, TypeError, AttributeError, ValueError) as err:
            raise StoreError(
                f"{product.directory / COEFFICIENTS_FILE}: not a launch fit ({err})"
            ) from None
        return cls(
            series=series,
            grid=product.read_frame(GRID_FILE, GRID_SCHEMA, meta),
            launcher=launcher,
            ridges=data.get("ridges", {}),
            key=data.get("key", ""),
        )


def fit_rows(
    rows: list[dict[str, Any]],
    fit: FitGridConfig,
    launcher: str,
    key: str = "",
    *,
    kept: LaunchFit | None = None,
) -> LaunchFit:
    """Fit every output over solved grid rows (``LaunchResult.to_row()``). ``kept``: a fit
    of the same ascents on another day, whose series of the outputs that do not depend on
    the day are taken as they are; only :data:`DAY_OUTPUTS` are fitted."""
    bad = [r for r in rows if not r["feasible"]]
    if bad:
        listing = ", ".join(f"{r['target_altitude_km']:g} km ({r['reason']})" for r in bad)
        raise ValueError(f"launch fit needs every grid point solved; infeasible: {listing}")
    grid = pd.DataFrame(sorted(rows, key=lambda row: row["target_altitude_km"]))
    h = grid["target_altitude_km"].to_numpy(dtype=float) * 1e3
    series, ridges = {}, {}
    for name, (unit, column) in FITTED_OUTPUTS.items():
        if kept is not None and name not in DAY_OUTPUTS:
            series[name], ridges[name] = kept.series[name], kept.ridges[name]
            continue
        y = grid[column].to_numpy(dtype=float)
        if name == "insertion_u_deg":
            y = np.degrees(np.unwrap(np.radians(y)))
        series[name], ridges[name] = fit_by_cross_validation(h, y, name, unit, fit)
    return LaunchFit(series=series, grid=grid, launcher=launcher, ridges=ridges, key=key)


def fit_by_cross_validation(
    h_m: np.ndarray, y: np.ndarray, name: str, unit: str, fit: FitGridConfig
) -> tuple[FourierSeries, float]:
    """The series whose ridge weight gives the smallest leave-one-out error.

    Each output has its own noise level (the payload is converged to grams, the
    insertion time only to a second: the optimum is flat in directions that move
    it), so each gets its own weight from the configured candidates.
    """
    best: tuple[FourierSeries, float] | None = None
    for ridge in fit.ridge_candidates:
        series = fit_fourier_series(
            h_m, y, name=name, unit=unit, order=fit.order, ridge=ridge, compute_loo=True
        )
        if best is None or series.loo_max_error < best[0].loo_max_error:
            best = (series, ridge)
    return best


def design_of(row: dict[str, Any]) -> dict[str, float]:
    """The design variables stored in a result row (configuration units)."""
    return {k.removeprefix("design_"): v for k, v in row.items() if k.startswith("design_")}


def launch_fit(
    inp: LaunchInput, fit: FitGridConfig, key: str = "", on_progress: Progress | None = None
) -> LaunchFit:
    """Solve the grid and fit it (the library path; the flow parallelises the grid);
    ``on_progress`` as :func:`solve_grid`'s."""
    rows = [r.to_row() for r in solve_grid(inp, fit, on_progress)]
    return fit_rows(rows, fit, inp.launcher.name, key)


def launch_fit_key(scenario: Scenario) -> str:
    """Content hash of everything a launch fit depends on (not the code version).

    The launch section (launcher, drop, day, bounds, settings, grid), the target's
    orbit (not its ``body``) and epoch (they set the plane) and the Earth model. The
    solvers' wall-time limits are left out: a fit exists only when every grid point was
    solved, so a limit never shaped one.
    """
    resolved = scenario.resolved()
    content = {k: resolved[k] for k in ("launch", "target", "epoch_utc", "earth")}
    # The target's body (its drag and radiation figures) moves no plane.
    content["target"] = {k: v for k, v in content["target"].items() if k != "body"}
    text = json.dumps(_without_time_limits(content), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def _without_time_limits(content: Any) -> Any:
    if isinstance(content, dict):
        return {k: _without_time_limits(v) for k, v in content.items() if k != "time_limit_s"}
    if isinstance(content, list):
        return [_without_time_limits(v) for v in content]
    return content


def find_launch_fit(scenario: Scenario, roots: tuple[Path, ...] | None = None) -> LaunchFit | None:
    """The stored fit solved for this scenario's launch (matching key), if any.

    Only complete fits count (a ``meta.json`` naming the key): a directory without one
    is an interrupted save, or a fit of an older format that is solved again. The fit
    found is loaded with every file checked.
    """
    return _stored_fit(launch_fit_key(scenario), roots)


def _stored_fit(key: str, roots: tuple[Path, ...] | None) -> LaunchFit | None:
    """The complete stored fit whose ``meta.json`` names ``key`` (first root first)."""
    for root in roots or fit_roots():
        candidates = [root / key, *sorted(root.glob("*"))] if root.is_dir() else []
        for directory in candidates:
            path = directory / MARKER
            if not path.is_file():
                continue
            meta = read_json(path)
            if isinstance(meta, dict) and meta.get("kind") == KIND and meta.get("key") == key:
                return LaunchFit.load(directory)
    return None


# -- one grid for every launch day (module notes) ---------------------------------------


def grid_launch_day(scenario: Scenario) -> str:
    """The launch day the shared grid is solved for: the campaign epoch's UTC date
    (``YYYY-MM-DD``), whatever the scenario's own launch day."""
    return scenario.epoch.iso()[:10]


def grid_scenario(scenario: Scenario) -> Scenario:
    """The scenario launched on :func:`grid_launch_day` (the target, its epoch and every
    setting unchanged): the problem the shared grid solves."""
    if scenario.launch is None:
        raise ValueError("the scenario has no launch section")
    launch = scenario.launch.model_copy(update={"launch_date_utc": grid_launch_day(scenario)})
    return scenario.model_copy(update={"launch": launch})


def launch_grid_key(scenario: Scenario) -> str:
    """Content hash of what the solved grid's ascents depend on: the launch section
    without its day, the Earth model, and the inclination of the target's mean plane on
    :func:`grid_launch_day` (exact, as the grid's problem takes it). Neither the launch
    day nor the target's node enters (a target of another node shares the grid when its
    inclination comes out to the same last bit; else it gets a grid of its own: a miss,
    never a wrong share); the solvers' wall-time limits are left out as in
    :func:`launch_fit_key`."""
    if scenario.launch is None:
        raise ValueError("the scenario has no launch section")
    resolved = scenario.resolved()
    day = Epoch.from_iso(grid_launch_day(scenario))
    content = {
        "launch": {k: v for k, v in resolved["launch"].items() if k != "launch_date_utc"},
        "earth": resolved["earth"],
        "target_inclination_rad": repr(float(target_plane_at(scenario, day).inclination_rad)),
    }
    text = json.dumps(_without_time_limits(content), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def find_launch_grid(scenario: Scenario, roots: tuple[Path, ...] | None = None) -> LaunchFit | None:
    """The stored grid the scenario's days share: one stored under
    :func:`launch_grid_key`, else the stored fit of :func:`grid_scenario` (solved for
    the grid day, e.g. the shipped reference of the default scenario); None without."""
    return _stored_fit(launch_grid_key(scenario), roots) or find_launch_fit(
        grid_scenario(scenario), roots
    )


def solve_launch_grid(scenario: Scenario, on_progress: Progress | None = None) -> LaunchFit:
    """Solve the shared grid (:func:`grid_scenario`'s launch fit, ~4 min here), store it in
    the workspace under :func:`launch_grid_key` and return it as stored."""
    key = launch_grid_key(scenario)
    inp = launch_input(grid_scenario(scenario))
    solved = launch_fit(inp, scenario.launch.fit, key=key, on_progress=on_progress)
    directory = fit_roots()[0] / key
    solved.save(directory)
    return LaunchFit.load(directory)


def retimed_launch_fit(grid: LaunchFit, scenario: Scenario) -> LaunchFit:
    """The scenario's launch fit from a shared grid: each grid design flown again by the
    stage (:func:`~ovtraj.launch.stage.finish_launch`) on the scenario's launch day, so
    every row's timing, insertion state and errors are the day's, checked against its
    tolerances, then fitted (key: :func:`launch_fit_key`). ``ValueError`` names the grid
    points the day cannot fly, or a grid that holds no solved rows."""
    if grid.grid.empty:
        raise ValueError("the shared launch grid holds no solved rows (coefficients only)")
    inp = launch_input(scenario)  # the day's plane, once
    stored = sorted(grid.grid.to_dict(orient="records"), key=lambda r: r["target_altitude_km"])
    rows = [_flown(inp, row) for row in stored]
    # The stage times each point at its first in-plane drop after 0 h. A day whose first
    # drop comes within the grid's spread of drop times (~3 min) would split the grid
    # between two crossings a day apart, and the insertion-time series would jump: the
    # points on the earlier crossing are timed on the later one, one return of the
    # target's plane over the drop point later (the step of stage.insertion_time_s).
    period = TWO_PI / (inp.earth.omega - inp.target_plane.raan_rate_rad_s)
    latest = max(row["insertion_time_s"] for row in rows)
    for k, row in enumerate(rows):
        if latest - row["insertion_time_s"] > period / 2.0:
            rows[k] = _flown(inp, stored[k], row["insertion_time_s"] + period)
    day = scenario.launch.launch_date_utc
    try:
        return fit_rows(
            rows, scenario.launch.fit, grid.launcher, key=launch_fit_key(scenario), kept=grid
        )
    except ValueError as err:
        raise ValueError(f"the shared launch grid on {day}: {err}") from None


def _flown(inp: LaunchInput, row: dict[str, Any], insertion_time: float | None = None) -> dict:
    """A stored grid row's design flown again on ``inp``'s day: its result row (no
    optimisation phases: the design is the grid's)."""
    point = inp.at_altitude(float(row["target_altitude_km"]) * 1e3)
    problem = launch_problem(point)
    x = problem.to_scaled(np.array([row[f"design_{n}"] for n in DESIGN_VARIABLES], dtype=float))
    evaluation = problem.evaluate(x)
    outcome = OptimisationOutcome(
        x=x,
        payload_kg=float(evaluation.payload_kg[0]),
        max_violation=float(evaluation.violation[0]),
        max_residual=float(evaluation.residual[0]),
        phases=[],
        trajectories=0,
        wall_time_s=0.0,
    )
    # wall time 0: the stored fit depends on its inputs only
    return finish_launch(point, problem, outcome, 0.0, insertion_time=insertion_time).to_row()


def grid_data(fit: LaunchFit) -> dict[str, Any]:
    """A fit with its solved grid as plain JSON data (:meth:`LaunchFit.to_dict` and the
    grid's rows): what a process with no stored grid on its disk (a Dask worker
    elsewhere) needs to retime it."""
    return {**fit.to_dict(), "grid": plain(fit.grid.to_dict(orient="records"))}


def grid_from_data(data: Any) -> LaunchFit:
    """The fit of :func:`grid_data`, its rows checked against :data:`GRID_SCHEMA`;
    ``ValueError`` naming what is malformed."""
    fit = LaunchFit.from_dict(data)
    rows = data.get("grid") if isinstance(data, dict) else None
    if not isinstance(rows, list) or not rows:
        raise ValueError("not a launch grid's data: no solved rows")
    table = table_from_rows(rows, GRID_SCHEMA, "launch grid")
    return LaunchFit(fit.series, table.to_pandas(), fit.launcher, fit.ridges, fit.key)


def day_launch_fit(
    scenario: Scenario, roots: tuple[Path, ...] | None = None, grid: LaunchFit | None = None
) -> LaunchFit | None:
    """The scenario's launch fit: the stored one (:func:`find_launch_fit`), else the
    shared grid (``grid``, else :func:`find_launch_grid`) retimed to its day, stored in the
    workspace under its key and returned as stored; None when there is no grid. One BLAS
    thread: any process derives the same bytes (a stored fit is never overwritten by
    another)."""
    found = find_launch_fit(scenario, roots)
    if found is not None:
        return found
    grid = grid or find_launch_grid(scenario, roots)
    if grid is None:
        return None
    with blas_threads(EVALUATION_BLAS_THREADS):
        fit = retimed_launch_fit(grid, scenario)
    directory = fit_roots()[0] / fit.key
    fit.save(directory)
    return LaunchFit.load(directory)
