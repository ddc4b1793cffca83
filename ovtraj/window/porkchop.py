"""The window's porkchop: each planned day's plan swept along one design variable.

A porkchop shows a cost over the launch day and a second variable. A day's pipeline
stores one plan, a design ``(H_P0, H_dp, t_dsp)``; its front is a few points scattered
in three dimensions, not a grid. So each planned day's plan is evaluated again by the
mission chain with ``configs/window.yaml`` ``porkchop.variable`` set to each of
``porkchop.points`` values spanning its ``mission.design_bounds`` (the same values every
day, the other two variables at the day's plan), in the day's own process with the
day's launch fit (:func:`sweep_day`): real evaluations, no surrogate, the same numbers
in any process (the batches' evaluation, :func:`ovtraj.runs.execute.evaluate_batch`).

The sweep is stored in the day's record (``sweep``, checked when read again by
:func:`sweep_problem`), so a resumed scan keeps it, and in the window's
``porkchop.parquet`` (:data:`PORKCHOP_SCHEMA`, :func:`porkchop_rows`), which the plot
is drawn from (:func:`porkchop_grid`, :func:`ovtraj.plots.porkchop.porkchop_figure`).
A column of the porkchop is one day's plan varied; between days the contours
interpolate between plans of different days. The values and the variable are part of
the window's id (:func:`ovtraj.window.scan.window_id`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import pairwise
from typing import Any

import numpy as np
import pandas as pd

from ovtraj.config import Scenario
from ovtraj.launch.launch_fit import LaunchFit
from ovtraj.mission import DESIGN_NAMES
from ovtraj.store.records import BOOL, FLOAT, INT, TEXT, record_schema
from ovtraj.units import S_PER_HOUR
from ovtraj.window.settings import MAX_SWEEP_POINTS, PorkchopSettings

__all__ = [
    "OUTCOME_KEYS",
    "PORKCHOP_SCHEMA",
    "PorkchopGrid",
    "Sweep",
    "porkchop_grid",
    "porkchop_rows",
    "sweep_day",
    "sweep_problem",
    "window_sweep",
]

# A day's ``sweep``: the variable, its values, and per value the chain's outcome.
OUTCOME_KEYS = ("feasible", "failed_stage", "t_total_s", "dv_total_mps", "m_load_kg")
SWEEP_KEYS = ("variable", "values", *OUTCOME_KEYS)
OBJECTIVE_KEYS = ("t_total_s", "dv_total_mps", "m_load_kg")

PORKCHOP_SCHEMA = record_schema(
    [
        ("day", INT),  # days after the scenario's launch day
        ("date", TEXT),  # the launch day, YYYY-MM-DD (UTC)
        ("node", INT),  # the position along the sweep, 0 at the variable's lower bound
        *[(name, FLOAT) for name in DESIGN_NAMES],  # the design evaluated
        ("feasible", BOOL),
        ("failed_stage", TEXT),  # the stage that failed, for an infeasible design
        ("t_total_h", FLOAT),  # the chain's objectives (None when infeasible)
        ("dv_total_mps", FLOAT),
        ("m_load_kg", FLOAT),
    ],
    required=("day", "date", "node", *DESIGN_NAMES, "feasible"),
)
"""``porkchop.parquet``: a row per planned day and sweep value, in (day, node) order."""


@dataclass(frozen=True)
class Sweep:
    """The design variable swept and its values (every day the same)."""

    variable: str
    values: tuple[float, ...]

    def as_data(self) -> dict[str, Any]:
        return {"variable": self.variable, "values": list(self.values)}

    @classmethod
    def from_data(cls, data: dict[str, Any]) -> Sweep:
        return cls(str(data["variable"]), tuple(float(v) for v in data["values"]))


def window_sweep(base: Scenario, settings: PorkchopSettings) -> Sweep:
    """``settings.points`` values evenly spanning ``settings.variable``'s
    ``mission.design_bounds`` (bounds no launch day moves)."""
    bounds = getattr(base.mission.design_bounds, settings.variable)
    values = np.linspace(bounds.lower, bounds.upper, settings.points)
    return Sweep(settings.variable, tuple(float(v) for v in values))


def sweep_day(
    scenario: Scenario, fit: LaunchFit, design: dict[str, float], sweep: Sweep
) -> dict[str, Any]:
    """The day's plan ``design`` with ``sweep.variable`` at each of its values, evaluated
    by the chain on the day (``scenario``, ``fit``): the record's ``sweep``."""
    from ovtraj.mission import MissionContext
    from ovtraj.runs.execute import evaluate_batch

    frame = pd.DataFrame([design | {sweep.variable: value} for value in sweep.values])
    records = evaluate_batch(MissionContext(scenario, fit), frame[list(DESIGN_NAMES)])
    totals = [record.totals() for record in records]
    return sweep.as_data() | {key: [t[key] for t in totals] for key in OUTCOME_KEYS}


def sweep_problem(data: Any, expected: Sweep | None = None) -> str | None:
    """Why ``data`` is not a planned day's ``sweep`` (with ``expected``: that sweep's
    variable and values); None when it is."""
    if not isinstance(data, dict) or sorted(data) != sorted(SWEEP_KEYS):
        return f"sweep is not an object of {', '.join(SWEEP_KEYS)}"
    variable, values = data["variable"], data["values"]
    if variable not in DESIGN_NAMES:
        return f"sweep variable is none of {', '.join(DESIGN_NAMES)}"
    if not isinstance(values, list) or not 2 <= len(values) <= MAX_SWEEP_POINTS:
        return f"sweep values are not a list of 2 to {MAX_SWEEP_POINTS}"
    if any(type(v) is not float or not math.isfinite(v) for v in values):
        return "sweep values are not finite numbers"
    if any(b <= a for a, b in pairwise(values)):
        return "sweep values do not increase"
    if expected is not None and (variable, tuple(values)) != (expected.variable, expected.values):
        return f"sweep is not this window's ({expected.variable}, {len(expected.values)} values)"
    for key in OUTCOME_KEYS:
        if not isinstance(data[key], list) or len(data[key]) != len(values):
            return f"sweep {key} does not have a value per point"
    for k, feasible in enumerate(data["feasible"]):
        if type(feasible) is not bool:
            return "sweep feasible is not true or false"
        numbers = [data[key][k] for key in OBJECTIVE_KEYS]
        failed = data["failed_stage"][k]
        if feasible and (
            failed is not None or any(type(v) is not float or not math.isfinite(v) for v in numbers)
        ):
            return f"sweep point {k}: feasible without finite objectives"
        if not feasible and (not isinstance(failed, str) or any(v is not None for v in numbers)):
            return f"sweep point {k}: infeasible without its failed stage"
    return None


def porkchop_rows(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """``porkchop.parquet``'s rows (:data:`PORKCHOP_SCHEMA`) of the day records: a row
    per sweep value of each day with a sweep (a planned day)."""
    rows = []
    for r in records:
        sweep = r.get("sweep")
        if sweep is None:
            continue
        design = {name: r[name] for name in DESIGN_NAMES}
        for k, value in enumerate(sweep["values"]):
            t_total = sweep["t_total_s"][k]
            rows.append(
                {
                    "day": r["day"],
                    "date": r["date"],
                    "node": k,
                    **(design | {sweep["variable"]: value}),
                    "feasible": sweep["feasible"][k],
                    "failed_stage": sweep["failed_stage"][k],
                    "t_total_h": None if t_total is None else t_total / S_PER_HOUR,
                    "dv_total_mps": sweep["dv_total_mps"][k],
                    "m_load_kg": sweep["m_load_kg"][k],
                }
            )
    return rows


@dataclass(frozen=True)
class PorkchopGrid:
    """The porkchop as arrays: ``values`` of ``variable`` (rows) by ``dates`` (columns,
    every day of the window); ``objectives``: column name -> (values, days) array, NaN
    where a day has no plan or the design is infeasible; ``infeasible``: where a planned
    day's design is."""

    dates: tuple[str, ...]
    variable: str
    values: np.ndarray
    objectives: dict[str, np.ndarray]
    infeasible: np.ndarray


def porkchop_grid(
    table: pd.DataFrame, dates: Sequence[str], sweep: Sweep, columns: Sequence[str]
) -> PorkchopGrid:
    """``porkchop.parquet`` (``table``) as a :class:`PorkchopGrid` of the window's
    ``dates``; ``columns``: the objectives wanted (``t_total_h``, ...). Raises ValueError
    when a row is not on the grid (another variable's values, a day outside ``dates``)."""
    shape = (len(sweep.values), len(dates))
    objectives = {name: np.full(shape, np.nan) for name in columns}
    infeasible = np.zeros(shape, dtype=bool)
    column_of = {date: j for j, date in enumerate(dates)}
    for row in table.itertuples(index=False):
        j, k = column_of.get(row.date), int(row.node)
        if j is None or not 0 <= k < shape[0] or getattr(row, sweep.variable) != sweep.values[k]:
            raise ValueError(f"porkchop row day {row.day} node {row.node}: not on the sweep")
        infeasible[k, j] = not row.feasible
        for name in columns:
            value = getattr(row, name)
            objectives[name][k, j] = np.nan if value is None else float(value)
    values = np.asarray(sweep.values)
    return PorkchopGrid(tuple(dates), sweep.variable, values, objectives, infeasible)
