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

from ovtraj.config import Scenario
from ovtraj.config.launch import FitGridConfig
from ovtraj.launch.fourier import FourierSeries, fit_fourier_series
from ovtraj.launch.inputs import LaunchInput
from ovtraj.launch.result import ROW_SCHEMA, LaunchResult
from ovtraj.launch.stage import solve_launch
from ovtraj.store.files import Digest, StoreError, read_json
from ovtraj.store.paths import reference_dir, workspace
from ovtraj.store.products import Product
from ovtraj.store.records import table_from_rows

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
    rows: list[dict[str, Any]], fit: FitGridConfig, launcher: str, key: str = ""
) -> LaunchFit:
    """Fit every output over solved grid rows (``LaunchResult.to_row()``)."""
    bad = [r for r in rows if not r["feasible"]]
    if bad:
        listing = ", ".join(f"{r['target_altitude_km']:g} km ({r['reason']})" for r in bad)
        raise ValueError(f"launch fit needs every grid point solved; infeasible: {listing}")
    grid = pd.DataFrame(sorted(rows, key=lambda row: row["target_altitude_km"]))
    h = grid["target_altitude_km"].to_numpy(dtype=float) * 1e3
    series, ridges = {}, {}
    for name, (unit, column) in FITTED_OUTPUTS.items():
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
    # The target's body (its drag and radiation figures, issue 47) moves no plane.
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
    key = launch_fit_key(scenario)
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
