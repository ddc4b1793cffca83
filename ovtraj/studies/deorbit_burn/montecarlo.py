"""Monte Carlo of the closed-loop deorbit burn (seed sec. 4, figs. 14-17, Table 1).

Each run draws, from its own seeded generator (``numpy.random.default_rng([seed, run])``, so
a run does not depend on how runs are batched):

* the waiting orbit's mean semi-major axis error (seed: +-3 km) and a mean eccentricity
  error (seed: 0.004) added to the mean eccentricity vector in a uniformly random direction;
* a constant thrust-pointing error in pitch (added to the burn angle) and in yaw (out of
  plane) (seed: +-1 deg);
* a mass error (seed: 1 %, -950 to 950 kg) and a thrust error (seed: 3 %, -360 to 360 N;
  the mass flow scales with it, the specific impulse is unchanged);

each uniform on [-bound, bound] or normal with sigma = bound / sigma_level, as configured.

The on-board computer knows its orbit (autonomous orbit determination, seed sec. 2 and 4:
"burn parameters determined on-line"), so with ``replan_initial_orbit`` the eq. 27
iteration is re-run on the dispersed orbit with the nominal vehicle, started from the
nominal plan shifted by the two-body change of the impulsive point; the burn angle stays the
nominal plan's. It does not know the vehicle errors: the burn is flown with them, and the
engine is cut by the strategy's prediction from the true state (strategy 1: predicted entry
u; strategy 2: predicted entry flight-path angle). Every strategy flies the same draws
(common random numbers), so the strategies are compared on equal terms.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa

from ovtraj.astro.angles import TWO_PI, wrap_to_pi
from ovtraj.astro.elements import NonsingularElements
from ovtraj.config.deorbit_burn import DispersionsConfig
from ovtraj.deadline import Deadline
from ovtraj.environment import require_pinned_kernel
from ovtraj.studies.deorbit_burn.flight import initial_state
from ovtraj.studies.deorbit_burn.powered import ThrustSettings
from ovtraj.studies.deorbit_burn.problem import DeorbitBurnProblem
from ovtraj.studies.deorbit_burn.result import DeorbitBurnResult
from ovtraj.studies.deorbit_burn.solve import BurnSolver

logger = logging.getLogger(__name__)

__all__ = [
    "RUN_SCHEMA",
    "SIMULATIONS",
    "STORED_RUN_SCHEMA",
    "TIMING_COLUMNS",
    "MonteCarloContext",
    "RunDispersion",
    "draw_dispersion",
    "monte_carlo_summary",
    "run_monte_carlo",
    "simulate_runs",
]

# Simulated Monte Carlo runs and flights in this process (tests assert on it: a cached
# re-run of the flow must not simulate anything).
SIMULATIONS = {"runs": 0, "flights": 0}

# One row per (run, strategy); the Parquet files of the flow have exactly this schema.
RUN_SCHEMA = pa.schema(
    [
        ("run", pa.int64()),
        ("strategy", pa.int64()),
        ("delta_a_km", pa.float64()),
        ("delta_ex", pa.float64()),
        ("delta_ey", pa.float64()),
        ("pitch_error_deg", pa.float64()),
        ("yaw_error_deg", pa.float64()),
        ("mass_error_kg", pa.float64()),
        ("thrust_error_n", pa.float64()),
        ("planned_u_open_deg", pa.float64()),
        ("planning_iterations", pa.int64()),
        ("planning_converged", pa.bool_()),
        ("ok", pa.bool_()),
        ("reason", pa.string()),
        ("dv_mps", pa.float64()),
        ("burn_duration_s", pa.float64()),
        ("entry_u_error_deg", pa.float64()),
        ("along_track_error_km", pa.float64()),
        ("entry_fpa_error_deg", pa.float64()),
        ("entry_speed_error_mps", pa.float64()),
        ("prediction_u_error_deg", pa.float64()),
        ("prediction_fpa_error_deg", pa.float64()),
        ("wall_time_s", pa.float64()),
    ]
)

TIMING_COLUMNS = ("wall_time_s",)
"""Columns of ``RUN_SCHEMA`` that time the run rather than describe its result."""

STORED_RUN_SCHEMA = pa.schema([f for f in RUN_SCHEMA if f.name not in TIMING_COLUMNS])
"""The stored rows: ``RUN_SCHEMA`` without timing (kept in the batch markers), so that two
Monte Carlo runs of one problem and seed write byte-identical files."""


@dataclass(frozen=True)
class RunDispersion:
    """One run's errors: a [m], mean eccentricity vector (ex, ey) [-], pitch and yaw [rad],
    mass and thrust as fractions of the nominal."""

    run: int
    delta_a_m: float
    delta_ex: float
    delta_ey: float
    pitch_rad: float
    yaw_rad: float
    mass_fraction: float
    thrust_fraction: float


def _sample(rng: np.random.Generator, distribution: str, sigma_level: float, bound: float) -> float:
    if distribution == "uniform":
        return float(rng.uniform(-bound, bound))
    return float(rng.normal(0.0, bound / sigma_level))


def draw_dispersion(config: DispersionsConfig, seed: int, run: int) -> RunDispersion:
    """The errors of run ``run`` (see the module notes); the same for any batching."""
    rng = np.random.default_rng([seed, run])

    def draw(item: Any, bound: float) -> float:
        return _sample(rng, item.distribution, item.sigma_level, bound)

    delta_a = draw(config.semi_major_axis, config.semi_major_axis.bound_km * 1e3)
    delta_e = draw(config.eccentricity, config.eccentricity.bound)
    direction = float(rng.uniform(0.0, TWO_PI))
    attitude = math.radians(config.attitude.bound_deg)
    return RunDispersion(
        run=run,
        delta_a_m=delta_a,
        delta_ex=delta_e * math.cos(direction),
        delta_ey=delta_e * math.sin(direction),
        pitch_rad=draw(config.attitude, attitude),
        yaw_rad=draw(config.attitude, attitude),
        mass_fraction=draw(config.mass, config.mass.bound_fraction),
        thrust_fraction=draw(config.thrust, config.thrust.bound_fraction),
    )


class MonteCarloContext:
    """The nominal plan every run starts from (built once per process and problem)."""

    def __init__(self, problem: DeorbitBurnProblem) -> None:
        self.problem = problem
        self.solver = BurnSolver(problem)
        self.nominal: DeorbitBurnResult = self.solver.solve(strategy=2)
        self.burn_angle_rad = math.radians(self.nominal.burn_angle_deg)
        if self.nominal.converged:
            self.u_open_rad = math.radians(self.nominal.u_open_deg)
            self.impulse = self.solver.impulse_at(self.solver.waiting_mean, self.burn_angle_rad)

    def dispersed_orbit(self, d: RunDispersion) -> NonsingularElements:
        w = self.problem.waiting
        return NonsingularElements(
            a=float(w.a) + d.delta_a_m,
            ex=float(w.ex) + d.delta_ex,
            ey=float(w.ey) + d.delta_ey,
            i=w.i,
            raan=w.raan,
            u=w.u,
        )

    def simulate(self, run: int, strategies: Sequence[int], seed: int) -> list[dict[str, Any]]:
        """The rows of one run, one per strategy (all strategies fly the same draws)."""
        start = time.perf_counter()
        problem, solver = self.problem, self.solver
        config = problem.config.monte_carlo
        d = draw_dispersion(config.dispersions, seed, run)
        base = {
            "run": run,
            "delta_a_km": d.delta_a_m / 1e3,
            "delta_ex": d.delta_ex,
            "delta_ey": d.delta_ey,
            "pitch_error_deg": math.degrees(d.pitch_rad),
            "yaw_error_deg": math.degrees(d.yaw_rad),
            "mass_error_kg": d.mass_fraction * problem.vehicle.mass_kg,
            "thrust_error_n": d.thrust_fraction * problem.vehicle.thrust_n,
        }
        if not self.nominal.converged:
            SIMULATIONS["runs"] += 1
            return [
                _row(
                    base, s, math.nan, 0, False, None, f"nominal plan: {self.nominal.reason}", start
                )
                for s in strategies
            ]
        orbit = self.dispersed_orbit(d)
        state0 = initial_state(problem, orbit)
        nominal_thrust = solver.nominal_thrust(self.burn_angle_rad)
        mass = problem.vehicle.mass_kg
        u_open, iterations, planned = self.u_open_rad, 0, True
        if config.replan_initial_orbit:
            impulse = solver.impulse_at(solver.mean_elements(orbit), self.burn_angle_rad)
            guess = self.u_open_rad
            if impulse is not None and self.impulse is not None:
                guess += impulse.u_rad - self.impulse.u_rad
            limit = Deadline(problem.config.guidance.time_limit_s, "guidance.time_limit_s")
            plan = solver.plan(state0, guess, nominal_thrust, mass, limit)
            SIMULATIONS["flights"] += plan.iterations
            u_open, iterations, planned = plan.flight.u_open_rad, plan.iterations, plan.converged
            if not plan.flight.ok:
                SIMULATIONS["runs"] += 1
                reason = f"planning: {plan.reason}"
                return [
                    _row(base, s, u_open, iterations, False, None, reason, start)
                    for s in strategies
                ]
        actual = ThrustSettings(
            thrust_n=nominal_thrust.thrust_n * (1.0 + d.thrust_fraction),
            mass_flow_kg_s=nominal_thrust.mass_flow_kg_s * (1.0 + d.thrust_fraction),
            burn_angle_rad=self.burn_angle_rad + d.pitch_rad,
            yaw_rad=d.yaw_rad,
        )
        rows = []
        for strategy in strategies:
            flight = solver.simulator.fly(
                state0, mass * (1.0 + d.mass_fraction), u_open, actual, strategy
            )
            SIMULATIONS["flights"] += 1
            rows.append(_row(base, strategy, u_open, iterations, planned, flight, None, start))
        SIMULATIONS["runs"] += 1
        return rows


def _row(
    base: dict[str, Any],
    strategy: int,
    u_open: float,
    iterations: int,
    planned: bool,
    flight: Any,
    reason: str | None,
    start: float,
) -> dict[str, Any]:
    nan = math.nan
    f = flight
    ok = f is not None and f.ok
    row = dict(base)
    row.update(
        strategy=int(strategy),
        planned_u_open_deg=math.degrees(u_open) % 360.0 if math.isfinite(u_open) else nan,
        planning_iterations=int(iterations),
        planning_converged=bool(planned),
        ok=bool(ok),
        reason=reason if f is None else f.reason,
        dv_mps=nan if f is None else f.dv_mps,
        burn_duration_s=nan if f is None else f.burn_duration_s,
        entry_u_error_deg=nan if f is None else math.degrees(f.u_error_rad),
        entry_fpa_error_deg=nan if f is None else math.degrees(f.fpa_error_rad),
        entry_speed_error_mps=nan if f is None else f.speed_error_mps,
        prediction_u_error_deg=(
            nan if f is None else math.degrees(wrap_to_pi(f.predicted_u_rad - f.entry_u_rad))
        ),
        prediction_fpa_error_deg=(
            nan if f is None else math.degrees(f.predicted_fpa_rad - f.entry_fpa_rad)
        ),
        wall_time_s=time.perf_counter() - start,
    )
    return row


def _frame(rows: list[dict[str, Any]], entry_radius_m: float) -> pd.DataFrame:
    for row in rows:
        row["along_track_error_km"] = math.radians(row["entry_u_error_deg"]) * entry_radius_m / 1e3
    table = pa.Table.from_pylist(rows, schema=RUN_SCHEMA)
    return table.to_pandas()


def simulate_runs(
    context: MonteCarloContext,
    runs: Sequence[int],
    strategies: Sequence[int],
    seed: int,
    on_progress: Callable[[int, int, str], None] | None = None,
) -> pd.DataFrame:
    """Rows (``RUN_SCHEMA``) of the given run numbers, every strategy, sorted by run;
    ``on_progress(runs done, runs, "runs")`` after each run (and a debug log line). Stored
    rows: refused on another OpenBLAS kernel than the pin (:mod:`ovtraj.environment`)."""
    require_pinned_kernel()
    rows: list[dict[str, Any]] = []
    for done, run in enumerate(runs, start=1):
        rows.extend(context.simulate(int(run), strategies, seed))
        logger.debug("deorbit-burn Monte Carlo run %d (%d/%d) flown", run, done, len(runs))
        if on_progress is not None:
            on_progress(done, len(runs), "runs")
    return _frame(rows, context.problem.entry.radius_m)


def run_monte_carlo(
    problem: DeorbitBurnProblem,
    n: int,
    strategy: int | Sequence[int],
    seed: int,
    *,
    first_run: int = 0,
    context: MonteCarloContext | None = None,
    on_progress: Callable[[int, int, str], None] | None = None,
) -> pd.DataFrame:
    """``n`` dispersed runs (numbers ``first_run`` ...) flown with the cut-off ``strategy``.

    ``strategy`` may be a list: every run then flies each strategy on the same draws. One
    row per run and strategy, columns of ``RUN_SCHEMA`` (errors actual minus target; the
    along-track error is the u error times r_E). A failed run keeps its row (``ok`` False,
    ``reason``); nothing is raised for it. ``on_progress`` as :func:`simulate_runs`'s.
    """
    strategies = [strategy] if isinstance(strategy, int) else list(strategy)
    context = context or MonteCarloContext(problem)
    runs = range(first_run, first_run + n)
    return simulate_runs(context, runs, strategies, seed, on_progress)


def monte_carlo_summary(frame: pd.DataFrame) -> pd.DataFrame:
    """Dispersion statistics per strategy: counts, mean, std, max |x| and 3 sigma.

    Columns: strategy, runs, failed, and for along-track error [km], entry fpa error [deg],
    entry u error [deg], entry speed error [m/s], prediction errors: ``<name>_mean``,
    ``<name>_std``, ``<name>_max_abs``; dv and burn duration mean, min and max.
    """
    rows = []
    for strategy, group in frame.groupby("strategy", sort=True):
        good = group[group["ok"]]
        row: dict[str, Any] = {
            "strategy": int(strategy),
            "runs": len(group),
            "failed": int((~group["ok"]).sum()),
        }
        for column in (
            "along_track_error_km",
            "entry_fpa_error_deg",
            "entry_u_error_deg",
            "entry_speed_error_mps",
            "prediction_u_error_deg",
            "prediction_fpa_error_deg",
        ):
            values = good[column].to_numpy(dtype=float)
            name = column
            row[f"{name}_mean"] = float(values.mean()) if len(values) else math.nan
            row[f"{name}_std"] = float(values.std(ddof=1)) if len(values) > 1 else math.nan
            row[f"{name}_max_abs"] = float(np.abs(values).max()) if len(values) else math.nan
        for column in ("dv_mps", "burn_duration_s"):
            values = good[column].to_numpy(dtype=float)
            row[f"{column}_mean"] = float(values.mean()) if len(values) else math.nan
            row[f"{column}_min"] = float(values.min()) if len(values) else math.nan
            row[f"{column}_max"] = float(values.max()) if len(values) else math.nan
        rows.append(row)
    return pd.DataFrame(rows)
